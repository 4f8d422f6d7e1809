#include "synthetic_scans.h"

#include <forest_slam/io/rawlog_writer.h>
#include <forest_slam/io/tum.h>
#include <forest_slam/pipeline/mapping_job.h>
#include <gtest/gtest.h>
#include <mrpt/obs/CObservationIMU.h>

#include <filesystem>
#include <fstream>

using namespace forest_slam;
namespace fs = std::filesystem;

namespace
{
/** x-spread of the rear wall points in the map: the rear wall is seen at
 * both ends of the sweep, where motion distortion is largest. */
double wallThickness(const map::CForestMap& m)
{
	std::vector<Eigen::Vector3f> e, p;
	m.collectNear({0, 0, 0}, 100, e, p);
	p.insert(p.end(), e.begin(), e.end());
	double lo = 1e9, hi = -1e9;
	for (const auto& q : p)
		if (q.x() < -8 && q.z() > -1.0)
		{
			lo = std::min<double>(lo, q.x());
			hi = std::max<double>(hi, q.x());
		}
	return hi - lo;
}

pipeline::MappingConfig trajectoryConfig(bool deskew)
{
	auto cfg = core::TrackedConfig::fromText(
	    std::string("[pipeline]\npose_source = trajectory\ndeskew = ") +
	        (deskew ? "true" : "false") +
	        "\n[forest_map]\nedge_voxel_m = 0.02\nplanar_voxel_m = 0.02\n",
	    "test.ini");
	return pipeline::MappingConfig::load(cfg);
}
}  // namespace

TEST(Pipeline, DeskewRemovesMotionDistortion)
{
	test_support::MovingSensorWorld w;  // 2 m/s: 0.2 m of motion per sweep
	const auto gt = w.groundTruth(3);
	double thickness[2];
	for (int deskew = 0; deskew < 2; deskew++)
	{
		pipeline::MappingPipeline p(trajectoryConfig(deskew), gt);
		p.process(
		    std::make_shared<mrpt::obs::CObservationRotatingScan>(w.scan(0)));
		ASSERT_EQ(p.stats().scans_mapped, 1u);
		thickness[deskew] = wallThickness(p.forestMap());
	}
	EXPECT_GT(thickness[0], 0.15) << "without deskew the wall is smeared";
	EXPECT_LT(thickness[1], 0.03) << "with deskew the wall is sharp";
}

TEST(Pipeline, TrajectoryStampsAreScanReferenceTimes)
{
	test_support::MovingSensorWorld w;
	const auto gt = w.groundTruth(5);
	pipeline::MappingPipeline p(trajectoryConfig(true), gt);
	for (int k = 0; k < 4; k++)
		p.process(
		    std::make_shared<mrpt::obs::CObservationRotatingScan>(w.scan(k)));
	ASSERT_EQ(p.trajectory().size(), 4u);
	for (int k = 0; k < 4; k++)
	{
		EXPECT_NEAR(p.trajectory()[k].t_s, w.t0_s + k * w.period_s, 1e-6);
		EXPECT_NEAR(p.trajectory()[k].pose.translation().x(),
		            w.speed_mps * k * w.period_s, 1e-6);
	}
}

TEST(Pipeline, BadScansAreCountedNotFatal)
{
	test_support::MovingSensorWorld w;
	const auto gt = w.groundTruth(5);
	pipeline::MappingPipeline p(trajectoryConfig(true), gt);
	p.process(std::make_shared<mrpt::obs::CObservationRotatingScan>(w.scan(2)));
	p.process(std::make_shared<mrpt::obs::CObservationRotatingScan>(
	    w.scan(1)));  // backwards
	auto empty = w.scan(3);
	empty.rangeImage.setZero();
	p.process(std::make_shared<mrpt::obs::CObservationRotatingScan>(empty));
	auto unknown = w.scan(4);
	unknown.lidarModel = "MYSTERY";
	p.process(std::make_shared<mrpt::obs::CObservationRotatingScan>(unknown));
	auto late = w.scan(40);  // beyond the poses
	p.process(std::make_shared<mrpt::obs::CObservationRotatingScan>(late));
	auto imu = std::make_shared<mrpt::obs::CObservationIMU>();
	imu->sensorLabel = "imu";
	p.process(imu);
	const auto& s = p.stats();
	EXPECT_EQ(s.scans_in, 5u);
	EXPECT_EQ(s.scans_mapped, 1u);
	EXPECT_EQ(s.scans_out_of_order, 1u);
	EXPECT_EQ(s.scans_empty, 1u);
	EXPECT_EQ(s.scans_unreadable, 1u);
	EXPECT_EQ(s.scans_outside_poses, 1u);
	EXPECT_EQ(s.imu, 1u);
}

TEST(Pipeline, TrajectorySourceNeedsPoses)
{
	EXPECT_THROW(pipeline::MappingPipeline(trajectoryConfig(true)),
	             std::invalid_argument);
}

TEST(MappingJob, DamagedRawlogStillWritesOutputs)
{
	const auto dir =
	    fs::temp_directory_path() / ("fs_job_" + std::to_string(::getpid()));
	fs::create_directories(dir);
	test_support::MovingSensorWorld w;
	const int n = 20;
	io::writeTum((dir / "gt.tum").string(), w.groundTruth(n + 1));
	const auto rawlog = (dir / "run.rawlog").string();
	{
		io::RawlogWriter wr(rawlog);
		for (int k = 0; k < n; k++) wr.write(w.scan(k));
		wr.close();
	}
	std::ofstream((dir / "map.ini").string())
	    << "[pipeline]\npose_source = trajectory\n";

	pipeline::MappingJob job;
	job.config_path = (dir / "map.ini").string();
	job.rawlog_path = rawlog;
	job.poses_path = (dir / "gt.tum").string();
	job.out_dir = (dir / "out_full").string();
	job.progress_tty = 0;
	const auto full = pipeline::runMapping(job);
	EXPECT_FALSE(full.input_damaged);
	EXPECT_EQ(full.stats.scans_mapped, static_cast<uint64_t>(n));
	EXPECT_EQ(io::readTum(job.out_dir + "/trajectory.tum").size(),
	          static_cast<size_t>(n));
	const auto m = pipeline::loadForestMap(job.out_dir + "/forest.map");
	EXPECT_GT(m->planarPointCount(), 1000u);

	// Cut the rawlog at 60 %: processing stops at the damage, outputs hold
	// the scans before it.
	const auto cut = (dir / "cut.rawlog").string();
	{
		std::ifstream in(rawlog, std::ios::binary);
		std::vector<char> buf(fs::file_size(rawlog) * 6 / 10);
		in.read(buf.data(), buf.size());
		std::ofstream(cut, std::ios::binary).write(buf.data(), buf.size());
	}
	job.rawlog_path = cut;
	job.out_dir = (dir / "out_cut").string();
	const auto part = pipeline::runMapping(job);
	EXPECT_TRUE(part.input_damaged);
	EXPECT_NE(part.damage_message.find(cut), std::string::npos);
	EXPECT_GT(part.stats.scans_mapped, 5u);
	EXPECT_LT(part.stats.scans_mapped, static_cast<uint64_t>(n));
	EXPECT_EQ(io::readTum(job.out_dir + "/trajectory.tum").size(),
	          part.stats.scans_mapped);
	EXPECT_NO_THROW(pipeline::loadForestMap(job.out_dir + "/forest.map"));
}

TEST(Pipeline, StaticPoseIsLevelledWithImuGravity)
{
	auto cfg = core::TrackedConfig::fromText(
	    "[pipeline]\npose_source = static\n", "s.ini");
	pipeline::MappingPipeline p(pipeline::MappingConfig::load(cfg));
	// Rig tilted by 10 deg roll: at rest the accelerometer (IMU frame =
	// vehicle frame here) measures +g along the rig's tilted "up".
	const double roll = 10 * M_PI / 180;
	const Eigen::Matrix3d R_tilt =
	    Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()).toRotationMatrix();
	const Eigen::Vector3d f = R_tilt.transpose() * Eigen::Vector3d(0, 0, 9.81);
	for (int i = 0; i < 50; i++)
	{
		auto imu = std::make_shared<mrpt::obs::CObservationIMU>();
		imu->sensorLabel = "imu";
		imu->set(mrpt::obs::IMU_X_ACC, f.x() + 0.01 * std::sin(i));
		imu->set(mrpt::obs::IMU_Y_ACC, f.y());
		imu->set(mrpt::obs::IMU_Z_ACC, f.z());
		p.process(imu);
	}
	test_support::MovingSensorWorld w;
	w.speed_mps = 0;
	p.process(std::make_shared<mrpt::obs::CObservationRotatingScan>(w.scan(0)));
	ASSERT_EQ(p.trajectory().size(), 1u);
	const Eigen::Matrix3d R = p.trajectory()[0].pose.linear();
	// The lidar's z axis expressed in the map is the tilted up vector.
	EXPECT_NEAR(R(2, 2), std::cos(roll), 1e-3);
	EXPECT_NEAR(std::atan2(R(2, 1), R(2, 2)), roll, 2e-3);
	// Heading removed: the lidar x axis has no y component in the map.
	EXPECT_NEAR(R(1, 0), 0, 1e-9);
	EXPECT_TRUE(p.trajectory()[0].pose.translation().isZero());
}

TEST(Pipeline, LevelledOrientationKeepsHeadingAlongX)
{
	const Eigen::Matrix3d lidar_on_vehicle =
	    Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
	const Eigen::Matrix3d R = pipeline::MappingPipeline::levelledOrientation(
	    Eigen::Vector3d(0, 0, 9.8), lidar_on_vehicle);
	EXPECT_TRUE(R.isIdentity(1e-9));
}

TEST(Pipeline, OdometryTracksAMovingSensor)
{
	// Walls ahead/behind, ground, wall ends: a fully constrained corridor
	// box. 2 m/s, no poses given: the lidar odometry must recover them.
	auto cfg = core::TrackedConfig::fromText(
	    "[pipeline]\npose_source = odometry\n", "o.ini");
	pipeline::MappingPipeline p(pipeline::MappingConfig::load(cfg));
	test_support::MovingSensorWorld w;
	// A stand of poles on both sides: with only the default five, nothing
	// but their silhouettes holds the pose across the motion (y).
	w.poles = {{5, 4}, {-6, -5}, {8, -6}, {-3, 6}, {2, -4}, {3, 3},  {-1, -3},
	           {6, 2}, {9, 5},   {-4, 3}, {1, 5},  {4, -2}, {7, -3}, {10, -4}};
	const int n = 25;
	for (int k = 0; k < n; k++)
		p.process(
		    std::make_shared<mrpt::obs::CObservationRotatingScan>(w.scan(k)));
	ASSERT_EQ(p.trajectory().size(), static_cast<size_t>(n));
	EXPECT_EQ(p.stats().scans_unregistered, 0u);
	double worst = 0;
	for (int k = 0; k < n; k++)
	{
		const Eigen::Vector3d truth = w.positionAt(w.t0_s + k * w.period_s);
		worst = std::max(worst,
		                 (p.trajectory()[k].pose.translation() - truth).norm());
	}
	EXPECT_LT(worst, 0.08) << "worst position error over " << n << " scans";
	EXPECT_EQ(p.stats().stage_ms.size(), static_cast<size_t>(n));
}

TEST(Pipeline, TreeLayerDetectDuringRunIsCheckedByName)
{
	auto cfg = core::TrackedConfig::fromText(
	    "[trees]\nlayer_detect_during_run = sometimes\n", "t.ini");
	try
	{
		pipeline::MappingConfig::load(cfg);
		FAIL() << "a bad layer_detect_during_run was accepted";
	}
	catch (const core::ConfigError& e)
	{
		const std::string what = e.what();
		EXPECT_NE(what.find("t.ini"), std::string::npos) << what;
		EXPECT_NE(what.find("layer_detect_during_run"), std::string::npos)
		    << what;
		EXPECT_NE(what.find("sometimes"), std::string::npos) << what;
	}
	auto ok = core::TrackedConfig::fromText(
	    "[trees]\nlayer_detect_during_run = false\n", "t.ini");
	EXPECT_EQ(pipeline::MappingConfig::load(ok).trees.layer_detect_during_run,
	          "false");
}
