// End-to-end runs of bag2rawlog and pcap2rawlog (exit codes, messages,
// outputs) and, when forest-sim is built, the simulator's --bag round trip.
#include <forest_slam/core/scan_points.h>
#include <forest_slam/io/rawlog_reader.h>

#include <gtest/gtest.h>
#include <mrpt/obs/CObservationGPS.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/obs/gnss_messages_ascii_nmea.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "bag_fixtures.h"
#include "test_helpers.h"

using namespace forest_slam;
using ingest_test::sharedData;
using ingest_test::TempDir;

namespace
{
struct Run
{
	int code = -1;
	std::string out, err;
};

Run run(const std::string& args, const TempDir& tmp)
{
	const std::string o = tmp / "stdout.txt", e = tmp / "stderr.txt";
	const std::string cmd = "cd '" + std::string(FOREST_SLAM_SOURCE_DIR) +
	                        "' && " + args + " > '" + o + "' 2> '" + e + "'";
	const int st = std::system(cmd.c_str());
	Run r;
	r.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
	auto slurp = [](const std::string& f)
	{
		std::ifstream in(f);
		std::stringstream ss;
		ss << in.rdbuf();
		return ss.str();
	};
	r.out = slurp(o);
	r.err = slurp(e);
	return r;
}

const std::string kBin = FOREST_SLAM_BIN_DIR;
const std::string kBag2 = kBin + "/bag2rawlog", kPcap2 = kBin + "/pcap2rawlog";

std::map<std::string, size_t> labelCounts(const std::string& rawlog)
{
	std::map<std::string, size_t> n;
	io::RawlogReader r(rawlog);
	while (auto o = r.next()) n[o->sensorLabel]++;
	EXPECT_FALSE(r.damaged());
	return n;
}
}  // namespace

TEST(IngestApps, Bag2RawlogUsage)
{
	TempDir tmp("app_usage");
	auto r = run(kBag2 + " --help", tmp);
	EXPECT_EQ(r.code, 0);
	EXPECT_NE(r.out.find("--list"), std::string::npos);
	EXPECT_EQ(run(kBag2, tmp).code, 2);
	r = run(kBag2 + " --bag x.bag --conifg a.ini --out o.rawlog", tmp);
	EXPECT_EQ(r.code, 2);
	EXPECT_NE(r.err.find("--conifg"), std::string::npos) << r.err;
	EXPECT_EQ(run(kBag2 + " --bag x.bag --config", tmp).code, 2);
	r = run(kBag2 + " --bag /nonexistent.bag --list", tmp);
	EXPECT_EQ(r.code, 1);
	EXPECT_NE(r.err.find("/nonexistent.bag"), std::string::npos) << r.err;
}

TEST(IngestApps, Bag2RawlogShippedIniWorksOutOfTheBox)
{
	TempDir tmp("app_vlp16");
	ingest_test::writeRos1Bag(tmp / "run.bag", {});
	auto r = run(kBag2 + " --bag " + (tmp / "run.bag") + " --list", tmp);
	ASSERT_EQ(r.code, 0) << r.err;
	EXPECT_NE(r.out.find("/velodyne_points"), std::string::npos);
	EXPECT_NE(r.out.find("extrinsics"), std::string::npos) << r.out;
	r = run(kBag2 + " --quiet --bag " + (tmp / "run.bag") +
	            " --config ini/bag-vlp16.ini --out " + (tmp / "run.rawlog"),
	        tmp);
	ASSERT_EQ(r.code, 0) << r.err;
	EXPECT_NE(r.out.find("observations out: 5"), std::string::npos) << r.out;
	// The labels the mapping INIs read.
	const auto n = labelCounts(tmp / "run.rawlog");
	EXPECT_EQ(n.at("lidar"), size_t(ingest_test::kScans));
	EXPECT_EQ(n.at("imu"),
	          size_t(ingest_test::kScans * ingest_test::kImuPerScan));
	EXPECT_EQ(n.at("gnss"), 2u);
	EXPECT_FALSE(std::filesystem::exists(
	    tmp / ("run.rawlog.tmp." + std::to_string(::getpid()))));
}

TEST(IngestApps, Bag2RawlogErrors)
{
	TempDir tmp("app_err");
	ingest_test::BagSpec spec;
	spec.chunk_bytes = 20000;
	ingest_test::writeRos1Bag(tmp / "run.bag", spec);
	// A typo in the INI: exit 2 naming the key, nothing written.
	std::ofstream(tmp / "typo.ini")
	    << "[bag2rawlog_lidar]\nlidar_modell = VLP16\n";
	auto r = run(kBag2 + " --bag " + (tmp / "run.bag") + " --config " +
	                 (tmp / "typo.ini") + " --out " + (tmp / "o.rawlog"),
	             tmp);
	EXPECT_EQ(r.code, 2);
	EXPECT_NE(r.err.find("lidar_modell"), std::string::npos) << r.err;
	EXPECT_FALSE(std::filesystem::exists(tmp / "o.rawlog"));
	// A truncated bag: exit 1 naming the damage, the output keeps the rest.
	std::filesystem::copy_file(tmp / "run.bag", tmp / "cut.bag");
	std::filesystem::resize_file(
	    tmp / "cut.bag", std::filesystem::file_size(tmp / "run.bag") / 2);
	r = run(kBag2 + " --quiet --bag " + (tmp / "cut.bag") +
	            " --config ini/bag-vlp16.ini --out " + (tmp / "cut.rawlog"),
	        tmp);
	EXPECT_EQ(r.code, 1);
	EXPECT_NE(r.err.find("truncated"), std::string::npos) << r.err;
	EXPECT_NE(r.err.find("holds the"), std::string::npos) << r.err;
	const auto n = labelCounts(tmp / "cut.rawlog");
	EXPECT_GE(n.at("lidar"), 1u);
}

TEST(IngestApps, Pcap2Rawlog)
{
	TempDir tmp("app_pcap");
	EXPECT_EQ(run(kPcap2 + " --help", tmp).code, 0);
	EXPECT_EQ(run(kPcap2 + " --pcap a.pcap --out b.rawlog", tmp).code, 2);
	EXPECT_EQ(
	    run(kPcap2 + " --pcap a.pcap --model VLP64 --out b.rawlog", tmp).code,
	    2);
	EXPECT_EQ(
	    run(kPcap2 + " --pcap a.pcap --model VLP16 --out b.rawlog --bogus", tmp)
	        .code,
	    2);
	auto r = run(kPcap2 + " --pcap /nonexistent.pcap --model VLP16 --out " +
	                 (tmp / "x.rawlog"),
	             tmp);
	EXPECT_EQ(r.code, 1);
	EXPECT_NE(r.err.find("/nonexistent.pcap"), std::string::npos) << r.err;
	r = run(kPcap2 + " --quiet --pcap " +
	            sharedData("mrpt/sample_velodyne_vlp16_gps.pcap") +
	            " --model VLP16 --lidar-pose \"0.1 0 1.2 90 0 0\" --out " +
	            (tmp / "v.rawlog"),
	        tmp);
	ASSERT_EQ(r.code, 0) << r.err;
	EXPECT_NE(r.out.find("revolutions written: 3"), std::string::npos) << r.out;
	io::RawlogReader rd(tmp / "v.rawlog");
	size_t scans = 0;
	while (auto o = rd.next())
		if (auto s =
		        std::dynamic_pointer_cast<mrpt::obs::CObservationRotatingScan>(
		            o))
		{
			EXPECT_NEAR(s->sensorPose.z(), 1.2, 1e-12);
			EXPECT_NEAR(s->sensorPose.yaw(), M_PI / 2, 1e-12);
			scans++;
		}
	EXPECT_EQ(scans, 3u);
}

TEST(IngestApps, ForestSimBagRoundTrip)
{
	const std::string sim = kBin + "/forest-sim";
	if (!std::filesystem::exists(sim)) GTEST_SKIP() << sim << " is not built";
	TempDir tmp("app_sim");
	// A short walk (about 15 s) keeps the test quick.
	std::ofstream(tmp / "sim.ini")
	    << "[sim]\nseed = 3\nthreads = 2\n"
	       "[world]\nmargin_m = 15\nopen_area_radius_m = 4\n"
	       "[trees]\nstems_per_ha = 300\n[trail]\nlength_m = 2\n"
	       "[structures]\nbuildings = 0\nvehicles = 0\n"
	       "[motion]\ntype = handheld\nloop_radius_x_m = 5\n"
	       "loop_radius_y_m = 5\ninner_loop_radius_m = 0\n"
	       "start_pause_s = 0.5\nend_pause_s = 0.5\n"
	       "[lidar]\nmodel = VLP16\nazimuth_step_deg = 0.4\n";
	const std::string out = tmp / "sim";
	auto r = run(sim + " --config " + (tmp / "sim.ini") + " --out " + out +
	                 " --bag " + out + "/run.bag --log-level warn",
	             tmp);
	ASSERT_EQ(r.code, 0) << r.err;
	r = run(kBag2 + " --quiet --bag " + out +
	            "/run.bag --config ini/bag-vlp16.ini --out " +
	            (tmp / "conv.rawlog"),
	        tmp);
	ASSERT_EQ(r.code, 0) << r.err;

	struct Obs
	{
		std::vector<std::shared_ptr<mrpt::obs::CObservationRotatingScan>> scans;
		std::vector<std::shared_ptr<mrpt::obs::CObservationIMU>> imu;
		std::vector<std::shared_ptr<mrpt::obs::CObservationGPS>> gps;
	};
	auto load = [](const std::string& f)
	{
		Obs o;
		io::RawlogReader rd(f);
		while (auto x = rd.next())
		{
			if (auto s = std::dynamic_pointer_cast<
			        mrpt::obs::CObservationRotatingScan>(x))
				o.scans.push_back(s);
			if (auto i =
			        std::dynamic_pointer_cast<mrpt::obs::CObservationIMU>(x))
				o.imu.push_back(i);
			if (auto g =
			        std::dynamic_pointer_cast<mrpt::obs::CObservationGPS>(x))
				o.gps.push_back(g);
		}
		return o;
	};
	const Obs a = load(out + "/run.rawlog"), b = load(tmp / "conv.rawlog");
	ASSERT_GT(a.scans.size(), 50u);
	EXPECT_EQ(a.scans.size(), b.scans.size());
	EXPECT_EQ(a.imu.size(), b.imu.size());
	EXPECT_EQ(a.gps.size(), b.gps.size());
	size_t points = 0;
	double max_d = 0, max_dt = 0;
	for (size_t k = 0; k < std::min(a.scans.size(), b.scans.size()); k++)
	{
		const auto pa = core::unpackRotatingScan(*a.scans[k]);
		const auto pb = core::unpackRotatingScan(*b.scans[k]);
		ASSERT_EQ(pa.points.size(), pb.points.size()) << "scan " << k;
		for (size_t i = 0; i < pa.points.size(); i++)
		{
			const auto &p = pa.points[i], &q = pb.points[i];
			ASSERT_EQ(p.ring, q.ring);
			max_d = std::max({max_d, double(std::abs(p.x - q.x)),
			                  double(std::abs(p.y - q.y)),
			                  double(std::abs(p.z - q.z))});
			max_dt = std::max(
			    max_dt, std::abs((pa.stamp_s - pb.stamp_s) + (p.t_s - q.t_s)));
		}
		points += pa.points.size();
		EXPECT_TRUE(a.scans[k]->sensorPose == b.scans[k]->sensorPose ||
		            (a.scans[k]->sensorPose.asTPose() -
		             b.scans[k]->sensorPose.asTPose())
		                    .norm() < 1e-6);
	}
	std::cout << "round trip: " << b.scans.size() << " scans, " << points
	          << " points, max coordinate difference " << max_d
	          << " m, max time difference " << max_dt << " s\n";
	// Float32 coordinates up to 100 m: 1e-5 m is a few ulps.
	EXPECT_LT(max_d, 2e-5);
	EXPECT_LT(max_dt, 2e-6);
	for (size_t i = 0; i < std::min(a.imu.size(), b.imu.size()); i += 37)
	{
		EXPECT_NEAR(a.imu[i]->get(mrpt::obs::IMU_WZ),
		            b.imu[i]->get(mrpt::obs::IMU_WZ), 1e-12);
		EXPECT_NEAR(a.imu[i]->get(mrpt::obs::IMU_Z_ACC),
		            b.imu[i]->get(mrpt::obs::IMU_Z_ACC), 1e-12);
		EXPECT_NEAR(mrpt::Clock::toDouble(a.imu[i]->timestamp),
		            mrpt::Clock::toDouble(b.imu[i]->timestamp), 1e-6);
	}
	for (size_t i = 0; i < std::min(a.gps.size(), b.gps.size()); i++)
	{
		const auto& ga =
		    a.gps[i]->getMsgByClass<mrpt::obs::gnss::Message_NMEA_GGA>();
		const auto& gb =
		    b.gps[i]->getMsgByClass<mrpt::obs::gnss::Message_NMEA_GGA>();
		EXPECT_EQ(ga.fields.fix_quality == 0, gb.fields.fix_quality == 0);
		if (ga.fields.fix_quality)
		{
			EXPECT_NEAR(ga.fields.latitude_degrees, gb.fields.latitude_degrees,
			            1e-12);
		}
	}
}
