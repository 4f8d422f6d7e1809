// Issue 5, IMU and deskew: a robot turning in place at 45 deg/s sweeps a
// stem 4 degrees around the sensor during one revolution, smearing it. On a
// noise-free forest-sim run, the stem slice deskewed with our IMU rotation
// (odometry::deskewScan with the gyro, translation from the ground-truth
// velocity) must be as crisp as with the true per-firing poses: circle-fit
// residual < 1.5 x the ground-truth deskew's. The raw scan must be clearly
// worse, or the scan chosen would not test anything.
#include <forest_slam/core/scan_points.h>
#include <forest_slam/io/rawlog_reader.h>
#include <forest_slam/io/tum.h>
#include <forest_slam/odometry/lidar_odometry.h>
#include <forest_slam/trees/circle_fit.h>
#include <gtest/gtest.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>

using namespace forest_slam;
namespace fs = std::filesystem;

namespace
{
const char* kRobotTiny =
    R"(# a small forest, one lap of a 14 x 10 m rectangle, 45 deg/s turns
[sim]
seed = 1
noise = false
[world]
margin_m = 30
open_area_radius_m = 5
[terrain]
elevation_range_m = 1
feature_size_m = 40
[trees]
stems_per_ha = 600
[shrubs]
cover_fraction = 0.05
[trail]
length_m = 8
[structures]
buildings = 0
vehicles = 0
path_clearance_m = 1.0
[motion]
type = robot
speed_min_mps = 1.0
speed_max_mps = 1.5
loop_radius_x_m = 7
loop_radius_y_m = 5
loops = 1
corner_jitter_m = 0
stop_probability = 0
turn_rate_deg_s = 45
body_height_m = 0.3
inner_loop_radius_m = 0
[lidar]
model = VLP16
pose_x_m = 0.2
pose_z_m = 0.7
[imu]
pose_z_m = 0.15
)";

/** RMS distance to the Kasa circle of a stem slice (non-robust on purpose:
 * a smear must show). */
double sliceResidual(const std::vector<Eigen::Vector3d>& pts)
{
	trees::Points2D p;
	for (const auto& x : pts) p.emplace_back(x.x(), x.y());
	trees::Circle c;
	if (!trees::fitCircleKasa(p, c)) return 1e9;
	double s = 0;
	for (const auto& q : p)
	{
		const double e = (q - c.centre).norm() - c.radius_m;
		s += e * e;
	}
	return std::sqrt(s / p.size());
}
}  // namespace

TEST(DeskewOnSim, ImuDeskewKeepsStemsCrispInFastTurns)
{
	const std::string bin = FOREST_SLAM_BIN_DIR;
	if (!fs::exists(bin + "/forest-sim"))
		GTEST_SKIP() << "forest-sim is not built";
	const fs::path dir =
	    fs::temp_directory_path() / ("fs_deskew_" + std::to_string(::getpid()));
	fs::remove_all(dir);
	fs::create_directories(dir);
	std::ofstream((dir / "robot-tiny.ini").string()) << kRobotTiny;
	const std::string d = dir.string();
	ASSERT_EQ(std::system((bin + "/forest-sim --config " + d +
	                       "/robot-tiny.ini --out " + d + "/sim > " + d +
	                       "/sim.log 2>&1")
	                          .c_str()),
	          0)
	    << "see " << d << "/sim.log";
	const auto gt = io::readTum(d + "/sim/gt_trajectory.tum");

	// All IMU samples (body frame) and the scans.
	imu::ImuBuffer imu;
	std::vector<mrpt::obs::CObservationRotatingScan::Ptr> scans;
	io::RawlogReader reader(d + "/sim/run.rawlog");
	while (auto o = reader.next())
	{
		if (auto s =
		        std::dynamic_pointer_cast<mrpt::obs::CObservationRotatingScan>(
		            o))
			scans.push_back(s);
		else if (auto m =
		             std::dynamic_pointer_cast<mrpt::obs::CObservationIMU>(o))
		{
			using namespace mrpt::obs;
			mrpt::poses::CPose3D mount;
			m->getSensorPose(mount);
			const Eigen::Matrix3d R = mount.getRotationMatrix().asEigen();
			imu.add(mrpt::Clock::toDouble(m->timestamp),
			        R * Eigen::Vector3d(m->get(IMU_WX), m->get(IMU_WY),
			                            m->get(IMU_WZ)),
			        R * Eigen::Vector3d(m->get(IMU_X_ACC), m->get(IMU_Y_ACC),
			                            m->get(IMU_Z_ACC)));
		}
	}
	ASSERT_GT(scans.size(), 100u);

	// The scan with the fastest turn.
	size_t best = 0;
	double best_turn = 0;
	for (size_t k = 0; k < scans.size(); k++)
	{
		const double t = mrpt::Clock::toDouble(scans[k]->timestamp);
		Eigen::Isometry3d a, b;
		if (!core::interpolatePose(gt, t, a) ||
		    !core::interpolatePose(gt, t + scans[k]->sweepDuration, b))
			continue;
		const double turn =
		    Eigen::AngleAxisd((a.inverse() * b).linear()).angle();
		if (turn > best_turn) best_turn = turn, best = k;
	}
	ASSERT_GT(best_turn * 180 / M_PI, 3.0) << "no fast turn in the scenario";
	// Five scans around the fastest turn, each placed with the true pose of
	// its first firing (so only the deskew differs), stacked per stem:
	// without deskew each revolution puts the stem somewhere else.
	struct Slices
	{
		std::vector<Eigen::Vector3d> raw, imu, truth;
	};
	std::map<uint16_t, Slices> stems;
	for (size_t k = best >= 2 ? best - 2 : 0;
	     k <= std::min(scans.size() - 1, best + 2); k++)
	{
		const auto& obs = *scans[k];
		const auto sp = core::unpackRotatingScan(obs);
		const auto* label = sp.layer("gt_label");
		const auto* tree = sp.layer("gt_tree");
		ASSERT_TRUE(label && tree);
		const double t0 = sp.stamp_s;
		ASSERT_TRUE(imu.covers(t0, t0 + sp.sweep_s));
		Eigen::Isometry3d T0, T1;
		ASSERT_TRUE(core::interpolatePose(gt, t0, T0));
		ASSERT_TRUE(core::interpolatePose(gt, t0 + sp.sweep_s, T1));
		odometry::SweepMotion none, with_imu;
		none.t0_s = with_imu.t0_s = t0;
		none.sweep_s = with_imu.sweep_s = sp.sweep_s;
		with_imu.end = T0.inverse() * T1;  // translation: the true velocity
		with_imu.imu = &imu;
		with_imu.R_body_lidar = obs.sensorPose.getRotationMatrix().asEigen();
		const auto p_none = odometry::deskewScan(sp, none);
		const auto p_imu = odometry::deskewScan(sp, with_imu);
		ASSERT_EQ(p_none.size(), sp.points.size());
		for (size_t i = 0; i < sp.points.size(); i++)
		{
			const auto& q = sp.points[i];
			if ((*label)[i] != 2 || q.range_m > 10) continue;
			Eigen::Isometry3d Tt;
			ASSERT_TRUE(core::interpolatePose(gt, t0 + q.t_s, Tt));
			auto& s = stems[(*tree)[i]];
			s.raw.push_back(T0 * p_none[i].xyz.cast<double>());
			s.imu.push_back(T0 * p_imu[i].xyz.cast<double>());
			s.truth.push_back(Tt * Eigen::Vector3d(q.x, q.y, q.z));
		}
	}
	// A 0.6 m slice around the middle of each well-seen stem (taper and lean
	// stay small in it).
	int trees_tested = 0;
	double worst_raw_ratio = 0;
	for (auto& [id, s] : stems)
	{
		if (s.truth.size() < 150) continue;
		std::vector<double> z;
		for (const auto& p : s.truth) z.push_back(p.z());
		std::nth_element(z.begin(), z.begin() + z.size() / 2, z.end());
		const double zm = z[z.size() / 2];
		Slices sl;
		for (size_t i = 0; i < s.truth.size(); i++)
			if (std::abs(s.truth[i].z() - zm) < 0.3)
			{
				sl.raw.push_back(s.raw[i]);
				sl.imu.push_back(s.imu[i]);
				sl.truth.push_back(s.truth[i]);
			}
		if (sl.truth.size() < 40) continue;
		const double r_raw = sliceResidual(sl.raw),
		             r_imu = sliceResidual(sl.imu),
		             r_gt = sliceResidual(sl.truth);
		std::printf(
		    "stem %u (%zu points in 5 scans): circle residual raw %.4f m, IMU "
		    "deskew "
		    "%.4f m, true deskew %.4f m (turn %.1f deg per sweep)\n",
		    id - 1, sl.truth.size(), r_raw, r_imu, r_gt,
		    best_turn * 180 / M_PI);
		EXPECT_LT(r_imu, 1.5 * r_gt) << "stem " << id - 1;
		worst_raw_ratio = std::max(worst_raw_ratio, r_raw / r_gt);
		trees_tested++;
	}
	ASSERT_GE(trees_tested, 1) << "no stem seen well enough near the sensor";
	EXPECT_GT(worst_raw_ratio, 3.0)
	    << "the raw scans are not smeared: the test tests nothing";
	fs::remove_all(dir);
}
