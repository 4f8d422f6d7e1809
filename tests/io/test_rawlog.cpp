#include <forest_slam/io/rawlog_reader.h>
#include <forest_slam/io/rawlog_writer.h>
#include <gtest/gtest.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/obs/CObservationVelodyneScan.h>
#include <mrpt/system/datetime.h>

#include <filesystem>
#include <fstream>
#include <vector>

using namespace forest_slam;
namespace fs = std::filesystem;

namespace
{
std::string tmpFile(const std::string& name)
{
	return (fs::temp_directory_path() /
			("fs_rawlog_" + std::to_string(::getpid()) + "_" + name))
		.string();
}

void writeImuLog(const std::string& path, int n)
{
	io::RawlogWriter w(path);
	for (int i = 0; i < n; i++)
	{
		mrpt::obs::CObservationIMU imu;
		imu.sensorLabel = "imu";
		imu.timestamp = mrpt::Clock::fromDouble(100.0 + i * 0.005);
		imu.set(mrpt::obs::IMU_WZ, 0.01 * i);
		w.write(imu);
	}
	w.close();
}
}  // namespace

TEST(Rawlog, WriteThenStreamBack)
{
	const auto p = tmpFile("imu.rawlog");
	writeImuLog(p, 500);
	EXPECT_FALSE(fs::exists(p + ".tmp." + std::to_string(::getpid())));
	io::RawlogReader r(p);
	int n = 0;
	while (auto o = r.next())
	{
		auto imu = std::dynamic_pointer_cast<mrpt::obs::CObservationIMU>(o);
		ASSERT_TRUE(imu);
		EXPECT_NEAR(imu->get(mrpt::obs::IMU_WZ), 0.01 * n, 1e-12);
		n++;
	}
	EXPECT_EQ(n, 500);
	EXPECT_FALSE(r.damaged());
	EXPECT_DOUBLE_EQ(r.fractionRead(), 1.0);
	EXPECT_EQ(r.next(), nullptr);
}

TEST(Rawlog, UnclosedWriterLeavesNoFile)
{
	const auto p = tmpFile("abandoned.rawlog");
	{
		io::RawlogWriter w(p);
		mrpt::obs::CObservationIMU imu;
		w.write(imu);
	}
	EXPECT_FALSE(fs::exists(p));
}

TEST(Rawlog, TruncatedFileReportsRecordAndOffset)
{
	const auto p = tmpFile("full.rawlog");
	writeImuLog(p, 2000);
	// Cut the gzip file in the middle: everything before the cut must still
	// be read, then a RawlogError names the file and the record.
	const auto size = fs::file_size(p);
	const auto cut = tmpFile("cut.rawlog");
	{
		std::ifstream in(p, std::ios::binary);
		std::vector<char> buf(size / 2);
		in.read(buf.data(), buf.size());
		std::ofstream(cut, std::ios::binary).write(buf.data(), buf.size());
	}
	io::RawlogReader r(cut);
	int n = 0;
	std::string msg;
	uint64_t record = 0;
	try
	{
		while (r.next()) n++;
	}
	catch (const io::RawlogError& e)
	{
		msg = e.what();
		record = e.record;
		EXPECT_EQ(e.file, cut);
		EXPECT_GT(e.byte_offset, 0u);
	}
	EXPECT_TRUE(r.damaged()) << "read " << n << " records without error";
	EXPECT_GT(n, 100);
	EXPECT_LT(n, 2000);
	EXPECT_EQ(record, static_cast<uint64_t>(n));
	EXPECT_NE(msg.find(cut), std::string::npos) << msg;
	EXPECT_EQ(r.next(), nullptr);
}

TEST(Rawlog, GarbageFileIsAnErrorNotACrash)
{
	const auto p = tmpFile("garbage.rawlog");
	{
		std::ofstream f(p, std::ios::binary);
		for (int i = 0; i < 1000; i++) f.put(static_cast<char>((i * 37) & 0xff));
	}
	io::RawlogReader r(p);
	EXPECT_THROW(r.next(), io::RawlogError);
	EXPECT_THROW(io::RawlogReader("/nonexistent.rawlog"), std::runtime_error);
}

TEST(Rawlog, ReadsRealMrptRawlogs)
{
	const std::string dir = std::string(FOREST_SLAM_SHARED_DIR) + "/data/mrpt/";
	{
		io::RawlogReader r(dir + "rot_scan_velodyne.rawlog");
		auto o = r.next();
		auto rot = std::dynamic_pointer_cast<mrpt::obs::CObservationRotatingScan>(o);
		ASSERT_TRUE(rot);
		EXPECT_EQ(rot->rowCount, 16);
		EXPECT_GT(rot->columnCount, 1000);
		EXPECT_EQ(r.next(), nullptr);
	}
	{
		io::RawlogReader r(dir + "test_velodyne_VLP16.rawlog");
		auto o = r.next();
		EXPECT_TRUE(std::dynamic_pointer_cast<mrpt::obs::CObservationVelodyneScan>(o));
	}
}
