// The tiny scenario generated once without noise, then checked the way a
// user of the outputs would: stitching the scans with gt_trajectory.tum must
// reproduce gt_trees.csv DBH, integrating the IMU must reproduce the GT
// motion, the label layers must agree with the tree list, the GNSS fixes with
// the antenna track.
#include <forest_slam/core/scan_points.h>
#include <forest_slam/core/trajectory.h>
#include <forest_slam/io/rawlog_reader.h>
#include <forest_slam/io/tum.h>
#include <forest_slam/sim/options.h>
#include <forest_slam/sim/simulator.h>
#include <gtest/gtest.h>
#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/obs/CObservationGPS.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/topography/conversions.h>

#include <Eigen/Dense>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

using namespace forest_slam;
namespace fs = std::filesystem;

namespace
{
struct TreeRow
{
	int id;
	double x, y, z_ground, dbh, height;
	bool sapling;
};

std::vector<TreeRow> readTrees(const std::string& path)
{
	std::ifstream f(path);
	std::string line;
	std::getline(f, line);
	EXPECT_EQ(line, "id,x,y,z_ground,dbh_m,height_m,lean_deg,sapling");
	std::vector<TreeRow> out;
	while (std::getline(f, line))
	{
		for (char& c : line)
			if (c == ',') c = ' ';
		std::istringstream is(line);
		TreeRow r;
		double lean;
		int sap;
		is >> r.id >> r.x >> r.y >> r.z_ground >> r.dbh >> r.height >> lean >>
		    sap;
		r.sapling = sap != 0;
		out.push_back(r);
	}
	return out;
}

/** Algebraic (Kasa) circle fit: returns radius, centre in cx, cy. */
double fitCircle(const std::vector<Eigen::Vector2d>& p, double& cx, double& cy)
{
	Eigen::MatrixXd A(p.size(), 3);
	Eigen::VectorXd b(p.size());
	for (size_t i = 0; i < p.size(); i++)
	{
		A(i, 0) = p[i].x();
		A(i, 1) = p[i].y();
		A(i, 2) = 1;
		b(i) = -p[i].squaredNorm();
	}
	const Eigen::Vector3d s = A.colPivHouseholderQr().solve(b);
	cx = -s(0) / 2;
	cy = -s(1) / 2;
	return std::sqrt(cx * cx + cy * cy - s(2));
}

struct MapPoint
{
	Eigen::Vector3d p;
	uint16_t label, tree;
};

class TinyNoiseFree : public ::testing::Test
{
   protected:
	static void SetUpTestSuite()
	{
		dir_ = (fs::temp_directory_path() /
		        ("fs_sim_tiny_" + std::to_string(::getpid())))
		           .string();
		opts_ =
		    new sim::SimOptions(sim::SimOptions::loadFile("ini/sim-tiny.ini"));
		opts_->run.noise = false;
		sim::RunRequest req;
		req.out_dir = dir_;
		req.progress_tty = 0;
		result_ = new sim::RunResult(sim::runSimulation(*opts_, req));
		gt_ = new core::Trajectory(io::readTum(dir_ + "/gt_trajectory.tum"));
		trees_ = new std::vector<TreeRow>(readTrees(dir_ + "/gt_trees.csv"));
		// Read every observation once.
		io::RawlogReader rd(dir_ + "/run.rawlog");
		obs_ = new std::vector<mrpt::obs::CObservation::Ptr>();
		while (auto o = rd.next()) obs_->push_back(o);
	}
	static void TearDownTestSuite()
	{
		fs::remove_all(dir_);
		delete opts_;
		delete result_;
		delete gt_;
		delete trees_;
		delete obs_;
	}

	/** Every return of every scan in the map frame, via the GT poses. */
	static std::vector<MapPoint> stitch()
	{
		std::vector<MapPoint> out;
		for (const auto& o : *obs_)
		{
			auto s =
			    std::dynamic_pointer_cast<mrpt::obs::CObservationRotatingScan>(
			        o);
			if (!s) continue;
			const auto pts = core::unpackRotatingScan(*s);
			const auto* lab = pts.layer("gt_label");
			const auto* tree = pts.layer("gt_tree");
			EXPECT_TRUE(lab && tree);
			if (!lab || !tree) return out;
			for (size_t i = 0; i < pts.points.size(); i++)
			{
				const auto& p = pts.points[i];
				Eigen::Isometry3d T;
				EXPECT_TRUE(
				    core::interpolatePose(*gt_, pts.stamp_s + p.t_s, T, 1e-6));
				out.push_back({T * Eigen::Vector3d(p.x, p.y, p.z), (*lab)[i],
				               (*tree)[i]});
			}
		}
		return out;
	}

	static std::string dir_;
	static sim::SimOptions* opts_;
	static sim::RunResult* result_;
	static core::Trajectory* gt_;
	static std::vector<TreeRow>* trees_;
	static std::vector<mrpt::obs::CObservation::Ptr>* obs_;
};
std::string TinyNoiseFree::dir_;
sim::SimOptions* TinyNoiseFree::opts_ = nullptr;
sim::RunResult* TinyNoiseFree::result_ = nullptr;
core::Trajectory* TinyNoiseFree::gt_ = nullptr;
std::vector<TreeRow>* TinyNoiseFree::trees_ = nullptr;
std::vector<mrpt::obs::CObservation::Ptr>* TinyNoiseFree::obs_ = nullptr;

/** Pose of sensor b in the frame of sensor a (both on the vehicle). */
Eigen::Isometry3d relativePose(const mrpt::poses::CPose3D& a,
                               const mrpt::poses::CPose3D& b)
{
	const mrpt::poses::CPose3D r = b - a;
	Eigen::Isometry3d T;
	T.matrix() =
	    r.getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>().asEigen();
	return T;
}

Eigen::Matrix3d imuFromLidar(
    const std::vector<mrpt::obs::CObservation::Ptr>& obs)
{
	mrpt::poses::CPose3D lidar, imu;
	for (const auto& o : obs)
	{
		if (o->sensorLabel == "lidar") o->getSensorPose(lidar);
		if (o->sensorLabel == "imu") o->getSensorPose(imu);
	}
	// R_lidar_imu = R_body_lidar^T R_body_imu
	return lidar.getRotationMatrix().asEigen().transpose() *
	       imu.getRotationMatrix().asEigen();
}
}  // namespace

TEST_F(TinyNoiseFree, RunSummaryAndTrajectoryStartAndEnd)
{
	EXPECT_NEAR(result_->duration_s, 40, 6);
	EXPECT_EQ(
	    result_->scans,
	    static_cast<size_t>(std::floor((result_->duration_s - 0.0999) * 10)) +
	        1);
	ASSERT_GT(gt_->size(), 100u);
	// >= 100 Hz
	EXPECT_NEAR((*gt_)[1].t_s - (*gt_)[0].t_s, 1.0 / 200, 1e-6);
	// Starts at identity (map frame convention, level start), returns there.
	const auto& a = gt_->front().pose;
	const auto& b = gt_->back().pose;
	EXPECT_LT(a.translation().norm(), 1e-6);
	EXPECT_LT((a.linear() - Eigen::Matrix3d::Identity()).norm(), 1e-8);
	EXPECT_LT(b.translation().norm(), 1e-6);
	EXPECT_LT((b.linear() - Eigen::Matrix3d::Identity()).norm(), 1e-8);
	// It actually walked: ~40 m route.
	double len = 0;
	for (size_t i = 1; i < gt_->size(); i++)
		len += ((*gt_)[i].pose.translation() - (*gt_)[i - 1].pose.translation())
		           .norm();
	EXPECT_GT(len, 35);
}

TEST_F(TinyNoiseFree, StitchedStemSlicesReproduceGtDbh)
{
	const auto pts = stitch();
	std::map<int, std::vector<Eigen::Vector2d>> slices;
	std::map<int, const TreeRow*> by_id;
	for (const auto& t : *trees_) by_id[t.id] = &t;
	for (const auto& p : pts)
	{
		if (p.label != 2 || p.tree == 0) continue;
		const TreeRow* t = by_id.at(p.tree - 1);
		const double h = p.p.z() - t->z_ground;
		if (h >= 1.2 && h <= 1.4) slices[t->id].push_back(p.p.head<2>());
	}
	int evaluated = 0;
	double worst = 0;
	for (const auto& [id, xy] : slices)
	{
		const TreeRow* t = by_id.at(id);
		if (xy.size() < 100 || t->sapling) continue;
		// Well seen: points all around (>= 330 deg). Seen from one side, an
		// elliptic stem (up to 4 %) biases any circle fit by millimetres.
		std::vector<bool> bins(36, false);
		for (const auto& p : xy)
		{
			const double a = std::atan2(p.y() - t->y, p.x() - t->x);
			bins[std::min(35, static_cast<int>((a + M_PI) / (2 * M_PI) * 36))] =
			    true;
		}
		if (std::count(bins.begin(), bins.end(), true) < 33) continue;
		double cx, cy;
		const double r = fitCircle(xy, cx, cy);
		const double err = std::abs(2 * r - t->dbh);
		worst = std::max(worst, err);
		evaluated++;
		EXPECT_LT(err, 0.005)
		    << "tree " << id << " dbh " << t->dbh << " fit " << 2 * r;
		EXPECT_LT(std::hypot(cx - t->x, cy - t->y), 0.01) << "tree " << id;
	}
	EXPECT_GE(evaluated, 2) << "too few well-seen trees";
	RecordProperty("trees_evaluated", evaluated);
	RecordProperty("worst_dbh_error_mm", std::to_string(worst * 1000));
}

TEST_F(TinyNoiseFree, StemLabelsLieOnTheGtStems)
{
	const auto pts = stitch();
	std::map<int, const TreeRow*> by_id;
	for (const auto& t : *trees_) by_id[t.id] = &t;
	std::map<int, size_t> counts;
	size_t checked = 0;
	for (const auto& p : pts)
	{
		ASSERT_LE(p.label, 5);
		counts[p.label]++;
		if (p.label == 1 || p.label == 4 || p.label == 5)
		{
			EXPECT_EQ(p.tree, 0);
		}
		if (p.label == 2 || p.label == 3)
		{
			ASSERT_GT(p.tree, 0);
		}
		if (p.label != 2) continue;
		ASSERT_LE(p.tree, trees_->size());
		const TreeRow* t = by_id.at(p.tree - 1);
		const double h = p.p.z() - t->z_ground;
		if (t->sapling || h < 0.9 || h > 1.7) continue;
		// Constant-radius part of the stem: within ellipticity (4 %), bark
		// (3 mm) and the lean's offset from the breast-height axis point.
		const double d = std::hypot(p.p.x() - t->x, p.p.y() - t->y);
		EXPECT_NEAR(d, t->dbh / 2,
		            0.04 * t->dbh / 2 + 0.004 + 0.5 * std::tan(5 * M_PI / 180))
		    << "tree " << t->id;
		checked++;
	}
	EXPECT_GT(checked, 1000u);
	for (int l = 1; l <= 5; l++) EXPECT_GT(counts[l], 100u) << "label " << l;
}

TEST_F(TinyNoiseFree, GyroIntegrationOver10sMatchesGtRotation)
{
	const Eigen::Matrix3d R_li = imuFromLidar(*obs_);
	std::vector<std::pair<double, Eigen::Vector3d>> gyro;
	for (const auto& o : *obs_)
		if (auto m = std::dynamic_pointer_cast<mrpt::obs::CObservationIMU>(o))
			gyro.emplace_back(mrpt::Clock::toDouble(m->timestamp),
			                  Eigen::Vector3d(m->get(mrpt::obs::IMU_WX),
			                                  m->get(mrpt::obs::IMU_WY),
			                                  m->get(mrpt::obs::IMU_WZ)));
	ASSERT_GT(gyro.size(), 4000u);
	EXPECT_NEAR(gyro[1].first - gyro[0].first, 0.005, 1e-6);
	// From 5 s to 15 s: walking, swaying, turning.
	const double t0 = gt_->front().t_s;
	size_t i0 = 0;
	while (gyro[i0].first < t0 + 5) i0++;
	const size_t i1 = i0 + 2000;
	Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
	double turned = 0;
	for (size_t i = i0; i < i1; i++)
	{
		const double dt = gyro[i + 1].first - gyro[i].first;
		const Eigen::Vector3d w = 0.5 * (gyro[i].second + gyro[i + 1].second);
		turned += w.norm() * dt;
		R = R *
		    Eigen::AngleAxisd(w.norm() * dt, w.normalized()).toRotationMatrix();
	}
	Eigen::Isometry3d A, B;
	ASSERT_TRUE(core::interpolatePose(*gt_, gyro[i0].first, A));
	ASSERT_TRUE(core::interpolatePose(*gt_, gyro[i1].first, B));
	const Eigen::Matrix3d R_gt =
	    (A.linear() * R_li).transpose() * (B.linear() * R_li);
	const double err_deg =
	    Eigen::AngleAxisd(R_gt.transpose() * R).angle() * 180 / M_PI;
	EXPECT_LT(err_deg, 0.05);
	RecordProperty("gyro_10s_error_deg", std::to_string(err_deg));
	EXPECT_GT(turned * 180 / M_PI, 30);  // the test is not trivial
}

TEST_F(TinyNoiseFree, AccelerometerIntegratesToGtMotion)
{
	// Gravity-compensated double integration over 4 s from rest, using the
	// GT attitude: must land on the GT IMU position.
	mrpt::poses::CPose3D lidar_m, imu_m;
	std::vector<std::pair<double, Eigen::Vector3d>> acc;
	for (const auto& o : *obs_)
	{
		if (o->sensorLabel == "lidar") o->getSensorPose(lidar_m);
		if (auto m = std::dynamic_pointer_cast<mrpt::obs::CObservationIMU>(o))
		{
			m->getSensorPose(imu_m);
			acc.emplace_back(mrpt::Clock::toDouble(m->timestamp),
			                 Eigen::Vector3d(m->get(mrpt::obs::IMU_X_ACC),
			                                 m->get(mrpt::obs::IMU_Y_ACC),
			                                 m->get(mrpt::obs::IMU_Z_ACC)));
		}
	}
	const Eigen::Isometry3d T_li = relativePose(lidar_m, imu_m);
	// At rest and level: f = (0, 0, g).
	EXPECT_NEAR(acc[0].second.z(), opts_->imu.gravity_mps2, 1e-9);
	EXPECT_NEAR(acc[0].second.head<2>().norm(), 0.0, 1e-9);
	auto imuPose = [&](double t)
	{
		Eigen::Isometry3d T;
		EXPECT_TRUE(core::interpolatePose(*gt_, t, T));
		return Eigen::Isometry3d(T * T_li);
	};
	const Eigen::Vector3d g(0, 0, -opts_->imu.gravity_mps2);
	Eigen::Vector3d v = Eigen::Vector3d::Zero(),
	                p = imuPose(acc[0].first).translation();
	const size_t n = 800;  // 4 s: standing 2 s, then starting to walk
	for (size_t i = 0; i < n; i++)
	{
		const double dt = acc[i + 1].first - acc[i].first;
		const Eigen::Vector3d a0 =
		    imuPose(acc[i].first).linear() * acc[i].second + g;
		const Eigen::Vector3d a1 =
		    imuPose(acc[i + 1].first).linear() * acc[i + 1].second + g;
		p += v * dt + (2 * a0 + a1) / 6 * dt * dt;
		v += 0.5 * (a0 + a1) * dt;
	}
	const Eigen::Vector3d p_gt = imuPose(acc[n].first).translation();
	EXPECT_GT((p_gt - imuPose(acc[0].first).translation()).norm(),
	          1.0);  // it moved
	EXPECT_LT((p - p_gt).norm(), 0.02);
	RecordProperty("accel_4s_error_m", std::to_string((p - p_gt).norm()));
}

TEST_F(TinyNoiseFree, GnssFixesDecodeToTheAntennaTrack)
{
	// scenario.ini gives map <- world; world is ENU at the geodetic origin.
	mrpt::config::CConfigFileMemory ini;
	{
		std::ifstream f(dir_ + "/scenario.ini");
		std::stringstream s;
		s << f.rdbuf();
		ini.setContent(s.str());
	}
	std::istringstream xyz(
	    ini.read_string("ground_truth", "map_from_world_xyz_m", ""));
	std::istringstream quat(
	    ini.read_string("ground_truth", "map_from_world_quat_xyzw", ""));
	double x, y, z, qx, qy, qz, qw;
	ASSERT_TRUE(xyz >> x >> y >> z);
	ASSERT_TRUE(quat >> qx >> qy >> qz >> qw);
	Eigen::Isometry3d M = Eigen::Isometry3d::Identity();
	M.linear() = Eigen::Quaterniond(qw, qx, qy, qz).toRotationMatrix();
	M.translation() = Eigen::Vector3d(x, y, z);

	const auto& go = opts_->gnss;
	const mrpt::topography::TGeodeticCoords origin(
	    go.origin_lat_deg, go.origin_lon_deg, go.origin_height_m);
	mrpt::poses::CPose3D lidar_m;
	for (const auto& o : *obs_)
		if (o->sensorLabel == "lidar") o->getSensorPose(lidar_m);
	int fixes = 0;
	for (const auto& o : *obs_)
	{
		auto g = std::dynamic_pointer_cast<mrpt::obs::CObservationGPS>(o);
		if (!g) continue;
		const auto* gga =
		    g->getMsgByClassPtr<mrpt::obs::gnss::Message_NMEA_GGA>();
		const auto* best =
		    g->getMsgByClassPtr<mrpt::obs::gnss::Message_NV_OEM6_BESTPOS>();
		ASSERT_NE(gga, nullptr);
		ASSERT_NE(best, nullptr);
		if (gga->fields.fix_quality == 0) continue;
		// MRPT's GNSS messages are packed: copy before binding a reference
		// (EXPECT_EQ takes const double&; misaligned, UBSan).
		const double best_lat = best->fields.lat,
		             gga_lat = gga->fields.latitude_degrees;
		EXPECT_EQ(best_lat, gga_lat);
		mrpt::math::TPoint3D p;
		mrpt::topography::geodeticToENU_WGS84(
		    mrpt::topography::TGeodeticCoords(gga->fields.latitude_degrees,
		                                      gga->fields.longitude_degrees,
		                                      gga->fields.altitude_meters),
		    p, origin);
		mrpt::poses::CPose3D gnss_m;
		g->getSensorPose(gnss_m);
		const Eigen::Isometry3d T_lg = relativePose(lidar_m, gnss_m);
		Eigen::Isometry3d T;
		ASSERT_TRUE(core::interpolatePose(
		    *gt_, mrpt::Clock::toDouble(g->timestamp), T));
		const Eigen::Vector3d antenna = (T * T_lg).translation();
		EXPECT_LT((M * Eigen::Vector3d(p.x, p.y, p.z) - antenna).norm(), 0.005);
		fixes++;
	}
	EXPECT_GT(fixes, 30);
}

TEST_F(TinyNoiseFree, ScenarioIniRunsAgainAndRecordsFrames)
{
	const auto again = sim::SimOptions::loadFile(dir_ + "/scenario.ini");
	EXPECT_EQ(again.toIni(),
	          opts_->effective().toIni());  // noise switch applied
	std::ifstream f(dir_ + "/scenario.ini");
	std::stringstream s;
	s << f.rdbuf();
	for (const char* key : {"[ground_truth]", "map_from_world_xyz_m",
	                        "map_from_world_quat_xyzw", "map_origin_lat_deg",
	                        "origin_lat_deg", "return_to_start_translation_m"})
		EXPECT_NE(s.str().find(key), std::string::npos) << key;
}
