// forest-slam map --follow on a forest-sim rawlog that another process
// appends to in chunks (cutting records anywhere) gives exactly the offline
// run's trajectory.
#include <forest_slam/io/rawlog_reader.h>
#include <gtest/gtest.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/serialization/CArchive.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

#include "process_helpers.h"

using namespace forest_slam;
using namespace online_test;
namespace fs = std::filesystem;

namespace
{
/** The first `scans` lidar scans of a rawlog and everything before them,
 * as the bytes of a plain rawlog. */
std::vector<uint8_t> plainPrefix(const std::string& rawlog, int scans)
{
	io::RawlogReader r(rawlog);
	mrpt::io::CMemoryStream mem;
	auto arch = mrpt::serialization::archiveFrom(mem);
	int n = 0;
	while (auto o = r.next())
	{
		if (o->sensorLabel == "lidar" && n++ == scans) break;
		arch << *o;
	}
	const auto* p = static_cast<const uint8_t*>(mem.getRawBufferData());
	return std::vector<uint8_t>(p, p + mem.getTotalBytesCount());
}
}  // namespace

TEST(Follow, GrowingSimRawlogMapsLikeTheFinishedOne)
{
	const auto dir = tempDir("follow");
	Child sim({bin("forest-sim"), "--config", "ini/sim-tiny.ini", "--out",
	           dir + "/sim", "--progress", "log"},
	          dir + "/sim.log");
	ASSERT_EQ(sim.wait(300), 0) << sim.output();
	const auto bytes = plainPrefix(dir + "/sim/run.rawlog", 20);
	ASSERT_GT(bytes.size(), 100000u);
	{
		FILE* f = std::fopen((dir + "/full.rawlog").c_str(), "wb");
		std::fwrite(bytes.data(), 1, bytes.size(), f);
		std::fclose(f);
	}
	const std::string ini = "ini/vlp16-handheld.ini";
	Child offline(
	    {bin("forest-slam"), "map", "--config", ini, "--rawlog",
	     dir + "/full.rawlog", "--out", dir + "/offline", "--progress", "log"},
	    dir + "/offline.log");
	ASSERT_EQ(offline.wait(300), 0) << offline.output();

	// The follower starts before the file exists; the writer is another
	// process appending odd-sized chunks.
	const auto growing = dir + "/growing.rawlog";
	Child follow({bin("forest-slam"), "map", "--config", ini, "--rawlog",
	              growing, "--out", dir + "/follow", "--follow",
	              "--follow-timeout", "3", "--progress", "log"},
	             dir + "/follow.log");
	const pid_t writer = ::fork();
	if (writer == 0)
	{
		FILE* f = std::fopen(growing.c_str(), "ab");
		const size_t chunk = 97 * 1024 + 13;
		for (size_t i = 0; f && i < bytes.size(); i += chunk)
		{
			std::fwrite(bytes.data() + i, 1, std::min(chunk, bytes.size() - i),
			            f);
			std::fflush(f);
			::usleep(60 * 1000);
		}
		::_exit(f ? 0 : 1);
	}
	int st = 0;
	ASSERT_EQ(::waitpid(writer, &st, 0), writer);
	EXPECT_TRUE(WIFEXITED(st) && WEXITSTATUS(st) == 0);
	ASSERT_EQ(follow.wait(300), 0) << follow.output();
	EXPECT_EQ(fs::file_size(growing), bytes.size());

	const auto off = slurp(dir + "/offline/trajectory.tum");
	EXPECT_EQ(std::count(off.begin(), off.end(), '\n'), 21);  // + header
	EXPECT_EQ(slurp(dir + "/follow/trajectory.tum"), off);
	const auto summary = slurp(dir + "/follow/run_summary.json");
	EXPECT_NE(summary.find("\"scans_mapped\": 20"), std::string::npos)
	    << summary;
	EXPECT_NE(summary.find("\"input_damaged\": false"), std::string::npos)
	    << summary;
	fs::remove_all(dir);
}

TEST(Follow, RawlogGrabberOutputWhileItIsWritten)
{
	// MRPT's own rawlog-grabber (mrpt-apps) recording the VLP-16 capture
	// through CVelodyneScanner's pcap reader, as a gzip rawlog; it stops at
	// a key press (stdin), as a user would stop it.
	const std::string grabber = "/usr/bin/rawlog-grabber";
	if (!fs::exists(grabber))
		GTEST_SKIP() << "rawlog-grabber (mrpt-apps) not installed";
	const auto dir = tempDir("grabber");
	std::ofstream(dir + "/grab.ini")
	    << "[global]\nrawlog_prefix = " << dir
	    << "/dataset\ntime_between_launches = 300\nuse_sensoryframes = 0\n"
	       "GRABBER_PERIOD_MS = 200\n\n[VLP16]\ndriver = CVelodyneScanner\n"
	       "process_rate = 2000\nsensorLabel = VLP16\nmodel = VLP16\n"
	       "pcap_input = "
	    << FOREST_SLAM_SHARED_DIR
	    << "/data/mrpt/sample_velodyne_vlp16_gps.pcap\npcap_read_once = true\n"
	       "pcap_read_fast = false\npcap_read_full_scan_delay_ms = 300\n"
	       "pos_packets_timing_timeout = 0\n";
	std::ofstream(dir + "/map.ini")
	    << "[pipeline]\nlidar_label = VLP16_SCAN\ngnss_label = VLP16_GPS\n";
	// Stop once the grabber has saved the capture's scans (it logs "Saved"
	// per object; the capture holds 4 scans; at most 60 s), not after a
	// fixed time: on a loaded machine it once saved a single scan in 4 s.
	const std::string cmd =
	    "(for i in $(seq 600); do n=$(grep -c Saved " + dir +
	    "/grab.log 2>/dev/null); [ \"${n:-0}\" -ge 4 ] && break; sleep 0.1; "
	    "done; sleep 0.5; echo q) | " +
	    grabber + " " + dir + "/grab.ini > " + dir + "/grab.log 2>&1";
	const pid_t writer = ::fork();
	if (writer == 0) ::_exit(std::system(cmd.c_str()) == 0 ? 0 : 1);
	std::string rawlog;
	for (int i = 0; i < 300 && rawlog.empty(); i++)
	{
		for (const auto& e : fs::directory_iterator(dir))
			if (e.path().extension() == ".rawlog") rawlog = e.path().string();
		std::this_thread::sleep_for(std::chrono::milliseconds(20));
	}
	ASSERT_FALSE(rawlog.empty()) << slurp(dir + "/grab.log");
	Child follow({bin("forest-slam"), "map", "--config", dir + "/map.ini",
	              "--rawlog", rawlog, "--out", dir + "/follow", "--follow",
	              "--follow-timeout", "3", "--progress", "log"},
	             dir + "/follow.log");
	int st = 0;
	ASSERT_EQ(::waitpid(writer, &st, 0), writer);
	EXPECT_TRUE(WIFEXITED(st) && WEXITSTATUS(st) == 0)
	    << slurp(dir + "/grab.log");
	ASSERT_EQ(follow.wait(120), 0) << follow.output();
	EXPECT_NE(follow.output().find("gzip-compressed"), std::string::npos);
	Child offline(
	    {bin("forest-slam"), "map", "--config", dir + "/map.ini", "--rawlog",
	     rawlog, "--out", dir + "/offline", "--progress", "log"},
	    dir + "/offline.log");
	ASSERT_EQ(offline.wait(120), 0) << offline.output();
	const auto off = slurp(dir + "/offline/trajectory.tum");
	EXPECT_GE(std::count(off.begin(), off.end(), '\n'), 3);  // header + 2
	EXPECT_EQ(slurp(dir + "/follow/trajectory.tum"), off);
	fs::remove_all(dir);
}
