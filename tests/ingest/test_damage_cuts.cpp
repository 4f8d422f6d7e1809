// Issue 12: damaged recordings, cut at random (seeded) offsets or with
// garbage written over a stretch. Every reader must either refuse the file
// up front naming it, or convert/read what comes before the damage, name
// file and byte offset (or message index), and leave a valid output.
#include <forest_slam/core/config.h>
#include <forest_slam/ingest/bag_converter.h>
#include <forest_slam/ingest/pcap_converter.h>
#include <forest_slam/io/las.h>
#include <forest_slam/io/rawlog_reader.h>
#include <gtest/gtest.h>
#include <mrpt/obs/CObservationRotatingScan.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "bag_fixtures.h"
#include "test_helpers.h"

using namespace forest_slam;
using namespace forest_slam::ingest;
using ingest_test::sharedData;
using ingest_test::TempDir;
namespace fs = std::filesystem;

namespace
{
constexpr int kCuts = 6;

/** Seeded offsets in [lo, hi): the same cuts run after run. */
std::vector<uint64_t> cutOffsets(uint64_t lo, uint64_t hi, unsigned seed)
{
	std::mt19937_64 rng(seed);
	std::uniform_int_distribution<uint64_t> u(lo, hi - 1);
	std::vector<uint64_t> out;
	for (int i = 0; i < kCuts; i++) out.push_back(u(rng));
	return out;
}

void copyCut(const std::string& from, const std::string& to, uint64_t size)
{
	fs::remove(to);
	fs::copy_file(from, to);
	fs::permissions(to, fs::perms::owner_write, fs::perm_options::add);
	fs::resize_file(to, size);
}

/** Reads a rawlog to its end: the number of rotating scans; fails the test
 * if the file is damaged (an output must always be valid). */
size_t validRawlogScans(const std::string& path)
{
	io::RawlogReader r(path);
	size_t scans = 0;
	try
	{
		while (auto o = r.next())
			scans += bool(
			    std::dynamic_pointer_cast<mrpt::obs::CObservationRotatingScan>(
			        o));
	}
	catch (const io::RawlogError& e)
	{
		ADD_FAILURE() << "output rawlog is damaged: " << e.what();
	}
	return scans;
}

Bag2RawlogOptions options(const std::string& ini)
{
	auto cfg = core::TrackedConfig::fromText(ini, "test.ini");
	Bag2RawlogOptions o;
	o.loadFromConfigFile(cfg);
	cfg.checkNoUnknownKeys();
	return o;
}
}  // namespace

TEST(DamageCuts, Ros1BagCutAnywhere)
{
	TempDir tmp("cut_ros1");
	ingest_test::BagSpec spec;
	spec.chunk_bytes = 20000;
	writeRos1Bag(tmp / "full.bag", spec);
	const auto size = fs::file_size(tmp / "full.bag");
	const auto full =
	    convertBag(tmp / "full.bag", tmp / "full.rawlog", options(""), false);
	ASSERT_TRUE(full.ok()) << full.error;
	const size_t all = validRawlogScans(tmp / "full.rawlog");
	for (const auto at : cutOffsets(1, size, 1))
	{
		SCOPED_TRACE("cut at byte " + std::to_string(at) + " of " +
		             std::to_string(size));
		copyCut(tmp / "full.bag", tmp / "cut.bag", at);
		fs::remove(tmp / "cut.rawlog");
		try
		{
			const auto rep = convertBag(tmp / "cut.bag", tmp / "cut.rawlog",
			                            options(""), false);
			EXPECT_FALSE(rep.ok());
			EXPECT_NE(rep.error.find("byte"), std::string::npos) << rep.error;
			EXPECT_LE(validRawlogScans(tmp / "cut.rawlog"), all);
		}
		catch (const ConversionSetupError& e)
		{
			// Cut inside the bag header: nothing to convert, file named.
			EXPECT_NE(std::string(e.what()).find("cut.bag"), std::string::npos)
			    << e.what();
			EXPECT_FALSE(fs::exists(tmp / "cut.rawlog"));
		}
	}
}

TEST(DamageCuts, Ros2Db3CutAnywhere)
{
	TempDir tmp("cut_ros2");
	const std::string src = sharedData(
	    "nebula_velodyne_ros2/vlp16/1673400471837873222/"
	    "1673400471837873222_0.db3");
	const std::string ini =
	    "[bag2rawlog_lidar]\ntopic = /velodyne_packets\n"
	    "[bag2rawlog_imu]\ntopic =\n[bag2rawlog_gnss]\ntopic =\n";
	const auto size = fs::file_size(src);
	for (const auto at : cutOffsets(1, size, 2))
	{
		SCOPED_TRACE("cut at byte " + std::to_string(at) + " of " +
		             std::to_string(size));
		copyCut(src, tmp / "cut.db3", at);
		fs::remove(tmp / "out.rawlog");
		std::string what;
		try
		{
			const auto rep = convertBag(tmp / "cut.db3", tmp / "out.rawlog",
			                            options(ini), false);
			what = rep.error;
			EXPECT_FALSE(rep.ok());
			validRawlogScans(tmp / "out.rawlog");
		}
		catch (const ConversionSetupError& e)
		{
			what = e.what();
		}
		EXPECT_NE(what.find("cut.db3"), std::string::npos) << what;
	}
}

TEST(DamageCuts, PcapCutAnywhere)
{
	TempDir tmp("cut_pcap");
	const std::string src = sharedData("mrpt/sample_velodyne_vlp16_gps.pcap");
	PcapOptions o;
	const auto full = convertPcap(src, tmp / "full.rawlog", o, false);
	ASSERT_TRUE(full.error.empty()) << full.error;
	const auto size = fs::file_size(src);
	for (const auto at : cutOffsets(24, size, 3))
	{
		SCOPED_TRACE("cut at byte " + std::to_string(at) + " of " +
		             std::to_string(size));
		copyCut(src, tmp / "cut.pcap", at);
		const auto rep =
		    convertPcap(tmp / "cut.pcap", tmp / "cut.rawlog", o, false);
		EXPECT_NE(rep.error.find("cut.pcap"), std::string::npos) << rep.error;
		EXPECT_NE(rep.error.find("byte"), std::string::npos) << rep.error;
		EXPECT_LE(rep.revolutions, full.revolutions);
		EXPECT_EQ(validRawlogScans(tmp / "cut.rawlog"), rep.revolutions);
	}
}

TEST(DamageCuts, LasCutAnywhereKeepsTheRecordsBefore)
{
	TempDir tmp("cut_las");
	const std::string src = sharedData("treels/pine.las");
	const auto whole = io::readLas(src);
	const auto size = fs::file_size(src);
	for (const auto at : cutOffsets(1, size, 4))
	{
		SCOPED_TRACE("cut at byte " + std::to_string(at) + " of " +
		             std::to_string(size));
		copyCut(src, tmp / "cut.las", at);
		try
		{
			const auto c = io::readLas(tmp / "cut.las", true);
			// 227-byte header, 20-byte records (format 0).
			const size_t expect = (at - 227) / 20;
			ASSERT_EQ(c.size(), expect);
			EXPECT_NE(c.damage.find("cut.las: byte " +
			                        std::to_string(227 + 20 * expect)),
			          std::string::npos)
			    << c.damage;
			for (size_t i = 0; i < c.size(); i += 997)
				EXPECT_EQ(c.xyz[i], whole.xyz[i]);
			// Without `partial` the same file is refused, naming it.
			EXPECT_THROW(io::readLas(tmp / "cut.las"), io::CloudFileError);
		}
		catch (const io::CloudFileError& e)
		{
			EXPECT_LT(at, 227u) << e.what();  // only a cut header is fatal
			EXPECT_NE(std::string(e.what()).find("cut.las: byte"),
			          std::string::npos)
			    << e.what();
		}
	}
}

TEST(DamageCuts, RawlogCutOrOverwrittenAnywhere)
{
	TempDir tmp("cut_rawlog");
	writeRos1Bag(tmp / "full.bag", ingest_test::BagSpec{});
	for (const int level : {0, 1})  // plain and gzip
	{
		auto o = options("");
		o.compress_level = level;
		const std::string full =
		    tmp / ("full" + std::to_string(level) + ".rawlog");
		ASSERT_TRUE(convertBag(tmp / "full.bag", full, o, false).ok());
		size_t all = 0;
		{
			io::RawlogReader r(full);
			while (r.next()) all++;
		}
		const auto size = fs::file_size(full);
		for (const auto at : cutOffsets(1, size, 5 + level))
		{
			SCOPED_TRACE("level " + std::to_string(level) + ", cut at byte " +
			             std::to_string(at) + " of " + std::to_string(size));
			copyCut(full, tmp / "cut.rawlog", at);
			io::RawlogReader r(tmp / "cut.rawlog");
			size_t n = 0;
			try
			{
				while (r.next()) n++;
				// gzip: a cut inside the stream is noticed at its end.
				EXPECT_EQ(level, 1) << "plain rawlog cut without error";
			}
			catch (const io::RawlogError& e)
			{
				EXPECT_EQ(e.file, tmp / "cut.rawlog");
				EXPECT_LE(e.byte_offset, at);
				EXPECT_NE(std::string(e.what()).find("byte"),
				          std::string::npos);
			}
			EXPECT_LT(n, all);
		}
		// Garbage over 64 bytes somewhere (a bad sector): no crash, either
		// read through or stopped with file and offset.
		std::ifstream in(full, std::ios::binary);
		const std::vector<char> bytes((std::istreambuf_iterator<char>(in)),
		                              std::istreambuf_iterator<char>());
		std::mt19937 rng(7 + level);
		for (const auto at : cutOffsets(0, size - 64, 9 + level))
		{
			SCOPED_TRACE("garbage at byte " + std::to_string(at));
			auto d = bytes;
			for (int i = 0; i < 64; i++) d[at + i] = static_cast<char>(rng());
			std::ofstream(tmp / "bad.rawlog", std::ios::binary)
			    .write(d.data(), d.size());
			io::RawlogReader r(tmp / "bad.rawlog");
			try
			{
				while (r.next())
				{
				}
			}
			catch (const io::RawlogError& e)
			{
				EXPECT_EQ(e.file, tmp / "bad.rawlog");
			}
		}
	}
}
