// End to end: run the forest-sim binary on ini/sim-tiny.ini as a user would,
// check the command line contract, determinism across processes, the rawlog
// content, and read the ROS bag back with rosbag::View.
#include <forest_slam/core/scan_points.h>
#include <forest_slam/io/rawlog_reader.h>
#include <gtest/gtest.h>
#include <mrpt/obs/CObservationGPS.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>
#include <sys/wait.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

namespace fs = std::filesystem;
using namespace forest_slam;

namespace
{
struct AppRun
{
	int code = -1;
	std::string output;
};

AppRun run(const std::string& args)
{
	const std::string cmd =
	    std::string(FOREST_SLAM_BIN_DIR) + "/forest-sim " + args + " 2>&1";
	AppRun r;
	FILE* p = popen(cmd.c_str(), "r");
	std::array<char, 4096> buf;
	size_t n;
	while ((n = fread(buf.data(), 1, buf.size(), p)) > 0)
		r.output.append(buf.data(), n);
	const int st = pclose(p);
	r.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
	return r;
}

std::string slurp(const std::string& path)
{
	std::ifstream f(path, std::ios::binary);
	std::ostringstream s;
	s << f.rdbuf();
	return s.str();
}

double medianStep(std::vector<double> t)
{
	std::vector<double> d;
	for (size_t i = 1; i < t.size(); i++) d.push_back(t[i] - t[i - 1]);
	std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
	return d[d.size() / 2];
}

class ForestSimApp : public ::testing::Test
{
   protected:
	static void SetUpTestSuite()
	{
		base_ = (fs::temp_directory_path() /
		         ("fs_sim_app_" + std::to_string(::getpid())))
		            .string();
		fs::create_directories(base_);
		first_ = run("--config ini/sim-tiny.ini --seed 7 --out " + base_ +
		             "/a --bag " + base_ + "/a/run.bag --progress log");
	}
	static void TearDownTestSuite() { fs::remove_all(base_); }
	static std::string base_;
	static AppRun first_;
};
std::string ForestSimApp::base_;
AppRun ForestSimApp::first_;
}  // namespace

TEST_F(ForestSimApp, CommandLineContract)
{
	auto r = run("--help");
	EXPECT_EQ(r.code, 0);
	EXPECT_NE(r.output.find("--config"), std::string::npos);
	EXPECT_EQ(run("").code, 2);
	r = run("--config ini/sim-tiny.ini --out " + base_ + "/x --frobnicate");
	EXPECT_EQ(r.code, 2);
	EXPECT_NE(r.output.find("--frobnicate"), std::string::npos);
	EXPECT_EQ(run("--config ini/sim-tiny.ini").code, 2);  // no --out
	EXPECT_EQ(
	    run("--config ini/sim-tiny.ini --out " + base_ + "/x --seed -3").code,
	    2);
	r = run("--config ini/does-not-exist.ini --out " + base_ + "/x");
	EXPECT_EQ(r.code, 2);
	EXPECT_NE(r.output.find("does-not-exist.ini"), std::string::npos);
	// A typo in the INI: exit 2 naming file, section and key.
	const std::string bad = base_ + "/bad.ini";
	std::ofstream(bad) << slurp("ini/sim-tiny.ini")
	                   << "\n[lidar]\nrange_nosie_m = 0.02\n";
	r = run("--config " + bad + " --out " + base_ + "/x");
	EXPECT_EQ(r.code, 2);
	EXPECT_NE(r.output.find("bad.ini"), std::string::npos) << r.output;
	EXPECT_NE(r.output.find("lidar"), std::string::npos) << r.output;
	EXPECT_NE(r.output.find("range_nosie_m"), std::string::npos) << r.output;
	std::ofstream(bad) << "[trees]\ndbh_median_m = big\n";
	r = run("--config " + bad + " --out " + base_ + "/x");
	EXPECT_EQ(r.code, 2);
	EXPECT_NE(r.output.find("dbh_median_m"), std::string::npos) << r.output;
	EXPECT_FALSE(fs::exists(base_ + "/x/run.rawlog"));
	r = run("--config ini/sim-tiny.ini --dump-config");
	EXPECT_EQ(r.code, 0);
	EXPECT_NE(r.output.find("[motion]"), std::string::npos);
}

TEST_F(ForestSimApp, SameSeedGivesIdenticalFiles)
{
	ASSERT_EQ(first_.code, 0) << first_.output;
	const auto r = run("--config ini/sim-tiny.ini --seed 7 --out " + base_ +
	                   "/b --log-level warn");
	ASSERT_EQ(r.code, 0) << r.output;
	for (const char* f : {"run.rawlog", "gt_trajectory.tum", "gt_trees.csv",
	                      "gnss_map.csv", "scenario.ini"})
		EXPECT_TRUE(slurp(base_ + "/a/" + f) == slurp(base_ + "/b/" + f))
		    << f << " differs";
	EXPECT_GT(fs::file_size(base_ + "/a/run.rawlog"), 1000000u);
	EXPECT_NE(slurp(base_ + "/a/scenario.ini").find("seed = 7"),
	          std::string::npos);
}

TEST_F(ForestSimApp, RawlogHasScansImuGnssInTimeOrder)
{
	ASSERT_EQ(first_.code, 0) << first_.output;
	io::RawlogReader rd(base_ + "/a/run.rawlog");
	std::map<std::string, std::vector<double>> stamps;
	double last = 0;
	size_t with_layers = 0;
	while (auto o = rd.next())
	{
		const double t = mrpt::Clock::toDouble(o->timestamp);
		EXPECT_GE(t, last - 1e-9)
		    << "out of order at record " << rd.recordsRead();
		last = t;
		stamps[o->sensorLabel].push_back(t);
		if (auto s =
		        std::dynamic_pointer_cast<mrpt::obs::CObservationRotatingScan>(
		            o))
		{
			EXPECT_EQ(s->lidarModel, "VLP16");
			EXPECT_EQ(s->rowCount, 16);
			EXPECT_EQ(s->columnCount, 1800);
			EXPECT_NEAR(s->sweepDuration, 0.1 * 1799 / 1800, 1e-12);
			EXPECT_EQ(s->intensityImage.rows(), 16);
			if (s->rangeOtherLayers.count("gt_label") &&
			    s->rangeOtherLayers.count("gt_tree"))
				with_layers++;
			EXPECT_NO_THROW(core::unpackRotatingScan(*s));
		}
		else if (auto m =
		             std::dynamic_pointer_cast<mrpt::obs::CObservationIMU>(o))
		{
			EXPECT_TRUE(m->has(mrpt::obs::IMU_WZ));
			EXPECT_TRUE(m->has(mrpt::obs::IMU_Z_ACC));
		}
		else
			EXPECT_TRUE(
			    std::dynamic_pointer_cast<mrpt::obs::CObservationGPS>(o));
	}
	ASSERT_EQ(stamps.size(), 3u);
	EXPECT_NEAR(medianStep(stamps["lidar"]), 0.1, 1e-6);
	EXPECT_NEAR(medianStep(stamps["imu"]), 0.005, 1e-6);
	EXPECT_NEAR(medianStep(stamps["gnss"]), 1.0, 1e-6);
	EXPECT_EQ(with_layers, stamps["lidar"].size());
	EXPECT_GT(stamps["lidar"].size(), 350u);
}

TEST_F(ForestSimApp, BagReadsBackLikeAVelodyneRecording)
{
	ASSERT_EQ(first_.code, 0) << first_.output;
	// Reference: the rawlog's scans.
	std::vector<mrpt::obs::CObservationRotatingScan::Ptr> scans;
	size_t n_imu = 0, n_gnss = 0;
	{
		io::RawlogReader rd(base_ + "/a/run.rawlog");
		while (auto o = rd.next())
		{
			if (auto s = std::dynamic_pointer_cast<
			        mrpt::obs::CObservationRotatingScan>(o))
				scans.push_back(s);
			else if (o->sensorLabel == "imu")
				n_imu++;
			else
				n_gnss++;
		}
	}
	rosbag::Bag bag(base_ + "/a/run.bag");
	std::map<std::string, std::vector<double>> stamps;
	size_t cloud_i = 0, tf = 0, nofix = 0;
	double last_bag_time = 0;
	for (const rosbag::MessageInstance& m : rosbag::View(bag))
	{
		EXPECT_GE(m.getTime().toSec(), last_bag_time);
		last_bag_time = m.getTime().toSec();
		if (auto c = m.instantiate<sensor_msgs::PointCloud2>())
		{
			ASSERT_EQ(m.getTopic(), "/velodyne_points");
			stamps["cloud"].push_back(c->header.stamp.toSec());
			if (cloud_i >= scans.size()) continue;
			ASSERT_EQ(c->fields.size(), 6u);
			const char* names[6] = {"x", "y", "z", "intensity", "ring", "time"};
			const uint32_t offs[6] = {0, 4, 8, 12, 16, 18};
			const uint8_t types[6] = {7, 7, 7, 7, 4, 7};  // FLOAT32, UINT16
			for (int f = 0; f < 6; f++)
			{
				EXPECT_EQ(c->fields[f].name, names[f]);
				EXPECT_EQ(c->fields[f].offset, offs[f]);
				EXPECT_EQ(c->fields[f].datatype, types[f]);
			}
			EXPECT_EQ(c->point_step, 22u);
			EXPECT_EQ(c->header.frame_id, "velodyne");
			EXPECT_EQ(c->height, 1u);
			const auto& s = *scans[cloud_i];
			EXPECT_NEAR(c->header.stamp.toSec(),
			            mrpt::Clock::toDouble(s.timestamp), 1e-6);
			EXPECT_NEAR(m.getTime().toSec() - c->header.stamp.toSec(), 0.1,
			            1e-6);
			const auto pts = core::unpackRotatingScan(s);
			ASSERT_EQ(c->width, pts.points.size());
			// Spot-check points: same coordinates, ring and relative time.
			for (size_t i = 0; i < pts.points.size(); i += 997)
			{
				float xyz[3], t;
				uint16_t ring;
				std::memcpy(xyz, &c->data[i * 22], 12);
				std::memcpy(&ring, &c->data[i * 22 + 16], 2);
				std::memcpy(&t, &c->data[i * 22 + 18], 4);
				EXPECT_FLOAT_EQ(xyz[0], pts.points[i].x);
				EXPECT_FLOAT_EQ(xyz[2], pts.points[i].z);
				EXPECT_EQ(ring, pts.points[i].ring);
				EXPECT_FLOAT_EQ(t, pts.points[i].t_s);
				EXPECT_GE(t, 0.f);
				EXPECT_LE(t, 0.1f);
			}
			cloud_i++;
		}
		else if (auto imu = m.instantiate<sensor_msgs::Imu>())
		{
			EXPECT_EQ(m.getTopic(), "/imu/data");
			EXPECT_EQ(imu->orientation_covariance[0], -1);
			stamps["imu"].push_back(imu->header.stamp.toSec());
		}
		else if (auto fix = m.instantiate<sensor_msgs::NavSatFix>())
		{
			EXPECT_EQ(m.getTopic(), "/gps/fix");
			stamps["fix"].push_back(fix->header.stamp.toSec());
			if (fix->status.status == sensor_msgs::NavSatStatus::STATUS_NO_FIX)
				nofix++;
			else
			{
				EXPECT_NEAR(fix->latitude, 59.66, 0.01);
				EXPECT_GT(fix->position_covariance[0], 0);
			}
		}
		else if (auto t = m.instantiate<tf2_msgs::TFMessage>())
		{
			EXPECT_EQ(m.getTopic(), "/tf_static");
			EXPECT_EQ(t->transforms.size(), 3u);
			tf++;
		}
		else
			ADD_FAILURE() << "unexpected topic " << m.getTopic();
	}
	EXPECT_EQ(stamps["cloud"].size(), scans.size());
	EXPECT_EQ(stamps["imu"].size(), n_imu);
	EXPECT_EQ(stamps["fix"].size(), n_gnss);
	EXPECT_EQ(tf, 1u);
	EXPECT_NEAR(medianStep(stamps["cloud"]), 0.1, 1e-6);
	EXPECT_NEAR(medianStep(stamps["imu"]), 0.005, 1e-6);
	EXPECT_NEAR(medianStep(stamps["fix"]), 1.0, 1e-6);
	EXPECT_LT(nofix, stamps["fix"].size());
}
