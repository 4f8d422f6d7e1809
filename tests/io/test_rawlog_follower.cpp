// RawlogFollower: a rawlog read while another thread appends to it, in
// chunks that cut records anywhere; end conditions; gzip streams.
#include <forest_slam/io/rawlog_follower.h>
#include <forest_slam/io/rawlog_reader.h>
#include <gtest/gtest.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/system/datetime.h>
#include <zlib.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <thread>
#include <vector>

using namespace forest_slam;
namespace fs = std::filesystem;

namespace
{
std::string tmpFile(const std::string& name)
{
	const auto p = fs::temp_directory_path() /
	               ("fs_follow_" + std::to_string(::getpid()) + "_" + name);
	fs::remove(p);
	return p.string();
}

/** n IMU records (every 10th wrapped in a sensory frame) as rawlog bytes. */
std::vector<uint8_t> imuRecords(int n)
{
	mrpt::io::CMemoryStream mem;
	auto arch = mrpt::serialization::archiveFrom(mem);
	for (int i = 0; i < n; i++)
	{
		auto imu = std::make_shared<mrpt::obs::CObservationIMU>();
		imu->sensorLabel = "imu";
		imu->timestamp = mrpt::Clock::fromDouble(100.0 + i * 0.005);
		imu->set(mrpt::obs::IMU_WZ, 0.01 * i);
		if (i % 10 == 9)
		{
			mrpt::obs::CSensoryFrame sf;
			sf.insert(imu);
			arch << sf;
		}
		else
			arch << *imu;
	}
	const auto* p = static_cast<const uint8_t*>(mem.getRawBufferData());
	return std::vector<uint8_t>(p, p + mem.getTotalBytesCount());
}

/** Appends `bytes` to `path` in chunks of `chunk` bytes, `pause` apart. */
void appendSlowly(const std::string& path, const std::vector<uint8_t>& bytes,
                  size_t chunk, std::chrono::milliseconds pause)
{
	FILE* f = std::fopen(path.c_str(), "ab");
	ASSERT_NE(f, nullptr);
	for (size_t i = 0; i < bytes.size(); i += chunk)
	{
		std::fwrite(bytes.data() + i, 1, std::min(chunk, bytes.size() - i), f);
		std::fflush(f);
		std::this_thread::sleep_for(pause);
	}
	std::fclose(f);
}

void expectImuSequence(io::RawlogFollower& r, int n)
{
	for (int i = 0; i < n; i++)
	{
		const auto o = r.next();
		ASSERT_TRUE(o) << "observation " << i;
		const auto imu =
		    std::dynamic_pointer_cast<mrpt::obs::CObservationIMU>(o);
		ASSERT_TRUE(imu);
		EXPECT_NEAR(imu->get(mrpt::obs::IMU_WZ), 0.01 * i, 1e-12) << i;
	}
}
}  // namespace

TEST(RawlogFollower, ReadsAPlainRawlogWhileItGrowsInOddChunks)
{
	const auto path = tmpFile("plain.rawlog");
	const auto bytes = imuRecords(300);
	// 997-byte chunks cut records (~100 bytes each) at every possible place.
	std::thread writer(
	    [&] { appendSlowly(path, bytes, 997, std::chrono::milliseconds(2)); });
	io::FollowOptions opts;
	opts.idle_timeout_s = 2.0;
	opts.poll_period_s = 0.001;
	io::RawlogFollower r(path, opts);
	expectImuSequence(r, 300);
	writer.join();
	EXPECT_EQ(r.next(), nullptr);  // no growth for idle_timeout_s
	EXPECT_FALSE(r.stopped());
	EXPECT_FALSE(r.gzip());
	EXPECT_EQ(r.recordsRead(), 300u);
	EXPECT_EQ(r.bytesConsumed(), bytes.size());
	fs::remove(path);
}

TEST(RawlogFollower, WriterStoppingMidRecordIsDamageNamingTheOffset)
{
	const auto path = tmpFile("cut.rawlog");
	const auto one = imuRecords(1).size();
	auto bytes = imuRecords(3);
	bytes.resize(2 * one + one / 2);
	appendSlowly(path, bytes, bytes.size(), std::chrono::milliseconds(0));
	io::FollowOptions opts;
	opts.idle_timeout_s = 0.3;
	io::RawlogFollower r(path, opts);
	EXPECT_TRUE(r.next());
	EXPECT_TRUE(r.next());
	try
	{
		r.next();
		FAIL() << "expected RawlogError";
	}
	catch (const io::RawlogError& e)
	{
		EXPECT_EQ(e.record, 2u);
		EXPECT_EQ(e.byte_offset, 2 * one);
		EXPECT_NE(std::string(e.what()).find(path), std::string::npos)
		    << e.what();
		EXPECT_NE(std::string(e.what()).find("stopped growing"),
		          std::string::npos);
	}
	EXPECT_EQ(r.next(), nullptr);
	fs::remove(path);
}

TEST(RawlogFollower, FollowsAGzipStreamFlushedInBlocks)
{
	const auto path = tmpFile("stream.rawlog.gz");
	const auto bytes = imuRecords(200);
	std::thread writer(
	    [&]
	    {
		    gzFile g = gzopen(path.c_str(), "wb1");
		    ASSERT_NE(g, nullptr);
		    for (size_t i = 0; i < bytes.size(); i += 1500)
		    {
			    gzwrite(g, bytes.data() + i,
			            static_cast<unsigned>(
			                std::min<size_t>(1500, bytes.size() - i)));
			    gzflush(g, Z_SYNC_FLUSH);
			    std::this_thread::sleep_for(std::chrono::milliseconds(2));
		    }
		    gzclose(g);
	    });
	io::FollowOptions opts;
	opts.idle_timeout_s = 2.0;
	opts.poll_period_s = 0.001;
	io::RawlogFollower r(path, opts);
	expectImuSequence(r, 200);
	writer.join();
	EXPECT_EQ(r.next(), nullptr);
	EXPECT_TRUE(r.gzip());
	fs::remove(path);
}

TEST(RawlogFollower, StopRequestEndsTheWaitAndMissingFileIsNamed)
{
	const auto path = tmpFile("stop.rawlog");
	appendSlowly(path, imuRecords(2), 10000, std::chrono::milliseconds(0));
	io::FollowOptions opts;
	opts.idle_timeout_s = 1e6;  // only the stop request can end it
	bool stop = false;
	opts.should_stop = [&] { return stop; };
	io::RawlogFollower r(path, opts);
	EXPECT_TRUE(r.next());
	EXPECT_TRUE(r.next());
	stop = true;
	EXPECT_EQ(r.next(), nullptr);
	EXPECT_TRUE(r.stopped());
	fs::remove(path);

	io::FollowOptions quick;
	quick.idle_timeout_s = 0.2;
	try
	{
		io::RawlogFollower missing(tmpFile("never.rawlog"), quick);
		FAIL() << "expected an error";
	}
	catch (const std::runtime_error& e)
	{
		EXPECT_NE(std::string(e.what()).find("never.rawlog"),
		          std::string::npos);
	}
}
