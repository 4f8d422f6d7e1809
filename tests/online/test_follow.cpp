// forest-slam map --follow on a forest-sim rawlog that another process
// appends to in chunks (cutting records anywhere) gives exactly the offline
// run's trajectory.
#include <forest_slam/io/rawlog_reader.h>
#include <gtest/gtest.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/serialization/CArchive.h>

#include <cstdio>
#include <filesystem>

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
