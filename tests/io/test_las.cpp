// LAS / PLY / PCD readers: real files from TreeLS and fast_gicp, hand-made
// files with a known byte layout for every supported LAS point format, and
// truncated / invalid copies that must fail naming file and byte offset.
#include <forest_slam/io/las.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

using namespace forest_slam::io;
namespace fs = std::filesystem;

namespace
{
const std::string kShared = FOREST_SLAM_SHARED_DIR;

std::string tmpPath(const std::string& name)
{
	const auto dir = fs::temp_directory_path() /
	                 ("fs_test_las_" + std::to_string(::getpid()));
	fs::create_directories(dir);
	return (dir / name).string();
}

template <typename T>
void put(std::vector<char>& d, size_t off, T v)
{
	if (d.size() < off + sizeof(T)) d.resize(off + sizeof(T), 0);
	std::memcpy(d.data() + off, &v, sizeof(T));
}

void writeBytes(const std::string& path, const std::vector<char>& d)
{
	std::ofstream f(path, std::ios::binary);
	f.write(d.data(), static_cast<std::streamsize>(d.size()));
}

struct HandPoint
{
	double x, y, z;
	uint16_t intensity;
	uint8_t cls;
	double t;
};

/** A LAS file built byte by byte from the specification's tables, so the
 * reader is checked against the layout, not against itself. */
std::vector<char> makeLas(int minor, int format,
                          const std::vector<HandPoint>& pts,
                          int extra_bytes = 0)
{
	static const int kLen[9] = {20, 28, 26, 34, 0, 0, 30, 36, 38};
	const uint16_t rec = static_cast<uint16_t>(kLen[format] + extra_bytes);
	const uint16_t hdr = minor == 4 ? 375 : 227;
	const uint32_t vlr_bytes = 54 + 10;  // one VLR with a 10 byte payload
	std::vector<char> d(hdr + vlr_bytes, 0);
	std::memcpy(d.data(), "LASF", 4);
	d[24] = 1;
	d[25] = static_cast<char>(minor);
	put<uint16_t>(d, 94, hdr);
	put<uint32_t>(d, 96, hdr + vlr_bytes);
	put<uint32_t>(d, 100, 1);
	d[104] = static_cast<char>(format);
	put<uint16_t>(d, 105, rec);
	put<uint32_t>(d, 107, format >= 6 ? 0u : static_cast<uint32_t>(pts.size()));
	const double scale[3] = {0.001, 0.001, 0.01},
	             offset[3] = {500000.0, 6000000.0, 100.0};
	for (int i = 0; i < 3; i++)
	{
		put<double>(d, 131 + 8 * i, scale[i]);
		put<double>(d, 155 + 8 * i, offset[i]);
	}
	if (minor == 4) put<uint64_t>(d, 247, pts.size());
	for (const auto& p : pts)
	{
		std::vector<char> r(rec, 0);
		put<int32_t>(
		    r, 0,
		    static_cast<int32_t>(std::lround((p.x - offset[0]) / scale[0])));
		put<int32_t>(
		    r, 4,
		    static_cast<int32_t>(std::lround((p.y - offset[1]) / scale[1])));
		put<int32_t>(
		    r, 8,
		    static_cast<int32_t>(std::lround((p.z - offset[2]) / scale[2])));
		put<uint16_t>(r, 12, p.intensity);
		if (format >= 6)
		{
			r[16] = static_cast<char>(p.cls);
			put<double>(r, 22, p.t);
		}
		else
		{
			r[15] = static_cast<char>(p.cls |
			                          0x80);  // withheld flag must be masked
			if (format == 1 || format == 3) put<double>(r, 20, p.t);
		}
		d.insert(d.end(), r.begin(), r.end());
	}
	return d;
}

const std::vector<HandPoint> kPts = {
    {500001.234, 6000002.5, 101.25, 17, 2, 12.5},
    {500000.001, 5999999.999, 99.0, 65535, 5, 13.0},
    {500010.0, 6000020.0, 120.5, 0, 200, 14.25}};

std::string expectThrowMessage(const std::function<void()>& f)
{
	try
	{
		f();
	}
	catch (const CloudFileError& e)
	{
		return e.what();
	}
	ADD_FAILURE() << "expected CloudFileError";
	return "";
}
}  // namespace

TEST(Las, HandMadeEveryFormat)
{
	for (const auto& [minor, format] : std::vector<std::pair<int, int>>{{2, 0},
	                                                                    {2, 1},
	                                                                    {2, 2},
	                                                                    {2, 3},
	                                                                    {3, 1},
	                                                                    {4, 6},
	                                                                    {4, 7},
	                                                                    {4, 8},
	                                                                    {4, 1}})
	{
		SCOPED_TRACE("LAS 1." + std::to_string(minor) + " format " +
		             std::to_string(format));
		const auto path = tmpPath("f" + std::to_string(format) + "_" +
		                          std::to_string(minor) + ".las");
		writeBytes(path, makeLas(minor, format, kPts, format == 3 ? 4 : 0));
		const auto c = readLas(path);
		ASSERT_EQ(c.size(), kPts.size());
		const bool gps = format == 1 || format == 3 || format >= 6;
		EXPECT_EQ(c.gps_time_s.size(), gps ? kPts.size() : 0u);
		for (size_t i = 0; i < kPts.size(); i++)
		{
			EXPECT_NEAR(c.xyz[i].x(), kPts[i].x, 1e-6);
			EXPECT_NEAR(c.xyz[i].y(), kPts[i].y, 1e-6);
			EXPECT_NEAR(c.xyz[i].z(), kPts[i].z, 1e-6);
			EXPECT_EQ(c.intensity[i], kPts[i].intensity);
			// Formats 0–5 hold the class in 5 bits.
			EXPECT_EQ(c.classification[i],
			          format >= 6 ? kPts[i].cls : (kPts[i].cls & 0x1F));
			if (gps)
			{
				EXPECT_DOUBLE_EQ(c.gps_time_s[i], kPts[i].t);
			}
		}
	}
}

TEST(Las, InvalidAndTruncatedFilesNameFileAndOffset)
{
	const auto good = makeLas(2, 1, kPts);
	const auto path = tmpPath("bad.las");

	auto d = good;
	d[0] = 'X';
	writeBytes(path, d);
	auto msg = expectThrowMessage([&] { readLas(path); });
	EXPECT_NE(msg.find(path), std::string::npos) << msg;
	EXPECT_NE(msg.find("byte 0"), std::string::npos) << msg;
	EXPECT_NE(msg.find("signature"), std::string::npos) << msg;

	d = good;
	d[104] = 4;
	writeBytes(path, d);
	msg = expectThrowMessage([&] { readLas(path); });
	EXPECT_NE(msg.find("byte 104"), std::string::npos) << msg;
	EXPECT_NE(msg.find("format 4"), std::string::npos) << msg;

	d = good;
	d[104] = static_cast<char>(0x80 | 1);
	writeBytes(path, d);
	EXPECT_NE(expectThrowMessage([&] { readLas(path); }).find("LAZ"),
	          std::string::npos);

	d = good;
	put<uint32_t>(d, 107, 4);  // one point more than stored
	writeBytes(path, d);
	msg = expectThrowMessage([&] { readLas(path); });
	EXPECT_NE(msg.find("exceeds the file"), std::string::npos) << msg;
	EXPECT_NE(msg.find("byte " + std::to_string(good.size())),
	          std::string::npos)
	    << msg;

	d.assign(good.begin(), good.begin() + 100);
	writeBytes(path, d);
	EXPECT_NE(expectThrowMessage([&] { readLas(path); }).find("header"),
	          std::string::npos);

	EXPECT_THROW(readLas(tmpPath("does_not_exist.las")), CloudFileError);
}

TEST(Las, RealTreeLsFiles)
{
	const auto c = readLas(kShared + "/data/treels/pine_plot.las");
	ASSERT_EQ(c.size(), 114024u);
	Eigen::Vector3d lo = c.xyz[0], hi = c.xyz[0];
	for (const auto& p : c.xyz)
	{
		lo = lo.cwiseMin(p);
		hi = hi.cwiseMax(p);
	}
	// The header's bounding box: x, y in [0.0001, 9.9998], z in
	// [49.0418, 69.3673].
	EXPECT_NEAR(lo.x(), 0.0001, 1e-6);
	EXPECT_NEAR(hi.x(), 9.9998, 1e-6);
	EXPECT_NEAR(lo.z(), 49.0418, 1e-6);
	EXPECT_NEAR(hi.z(), 69.3673, 1e-6);
	EXPECT_TRUE(c.gps_time_s.empty());
	EXPECT_EQ(readLas(kShared + "/data/treels/pine.las").size(), 73851u);
	EXPECT_EQ(readCloudFile(kShared + "/data/treels/spruce.las").size(),
	          83392u);

	// A truncated copy of the real file fails with the file size as offset.
	std::ifstream in(kShared + "/data/treels/pine.las", std::ios::binary);
	std::vector<char> d((std::istreambuf_iterator<char>(in)),
	                    std::istreambuf_iterator<char>());
	d.resize(d.size() - 7);
	const auto path = tmpPath("pine_truncated.las");
	writeBytes(path, d);
	const auto msg = expectThrowMessage([&] { readCloudFile(path); });
	EXPECT_NE(msg.find("byte " + std::to_string(d.size())), std::string::npos)
	    << msg;
}

TEST(Pcd, RealBinaryAndHandMadeAscii)
{
	const auto c = readCloudFile(kShared + "/data/fast_gicp/251370668.pcd");
	ASSERT_EQ(c.size(), 69088u);
	ASSERT_EQ(c.intensity.size(), 69088u);
	for (const auto& p : c.xyz) ASSERT_TRUE(p.allFinite());
	double max_range = 0;
	for (const auto& p : c.xyz) max_range = std::max(max_range, p.norm());
	EXPECT_GT(max_range, 5.0);
	EXPECT_LT(max_range, 300.0);

	const auto path = tmpPath("a.pcd");
	{
		std::ofstream f(path);
		f << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F "
		     "F F U\n"
		     "COUNT 1 1 1 1\nWIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 "
		     "0\nPOINTS 3\nDATA ascii\n"
		     "1 2 3 7\nnan nan nan 0\n-1.5 0.25 1e2 9\n";
	}
	const auto a = readPcd(path);
	ASSERT_EQ(a.size(), 2u);  // the NaN point is dropped
	EXPECT_EQ(a.xyz[1], Eigen::Vector3d(-1.5, 0.25, 100.0));

	// Binary PCD with doubles, then truncated.
	const auto bpath = tmpPath("b.pcd");
	std::string hdr =
	    "VERSION 0.7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\n"
	    "WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n";
	std::vector<char> d(hdr.begin(), hdr.end());
	for (double v : {1.0, 2.0, 3.0, 4.0, 5.0, 6.0}) put<double>(d, d.size(), v);
	writeBytes(bpath, d);
	const auto b = readPcd(bpath);
	ASSERT_EQ(b.size(), 2u);
	EXPECT_EQ(b.xyz[1], Eigen::Vector3d(4, 5, 6));
	d.resize(d.size() - 1);
	writeBytes(bpath, d);
	const auto msg = expectThrowMessage([&] { readPcd(bpath); });
	EXPECT_NE(msg.find("truncated"), std::string::npos) << msg;
	EXPECT_NE(msg.find(bpath), std::string::npos) << msg;
}

TEST(Ply, AsciiAndBinary)
{
	const auto path = tmpPath("a.ply");
	{
		std::ofstream f(path);
		f << "ply\nformat ascii 1.0\ncomment hand made\nelement vertex "
		     "2\nproperty double x\n"
		     "property double y\nproperty double z\nproperty uchar "
		     "intensity\nelement face 0\n"
		     "property list uchar int vertex_indices\nend_header\n1 2 3 4\n5 6 "
		     "7.5 8\n";
	}
	const auto a = readCloudFile(path);
	ASSERT_EQ(a.size(), 2u);
	EXPECT_EQ(a.xyz[1], Eigen::Vector3d(5, 6, 7.5));
	EXPECT_EQ(a.intensity[1], 8);

	const auto bpath = tmpPath("b.ply");
	std::string hdr =
	    "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty "
	    "float x\n"
	    "property float y\nproperty float z\nproperty ushort "
	    "intensity\nend_header\n";
	std::vector<char> d(hdr.begin(), hdr.end());
	for (int i = 0; i < 2; i++)
	{
		for (float v : {1.5f * (i + 1), -2.0f, 0.25f})
			put<float>(d, d.size(), v);
		put<uint16_t>(d, d.size(), static_cast<uint16_t>(1000 + i));
	}
	writeBytes(bpath, d);
	const auto b = readPly(bpath);
	ASSERT_EQ(b.size(), 2u);
	EXPECT_EQ(b.xyz[1], Eigen::Vector3d(3.0, -2.0, 0.25));
	EXPECT_EQ(b.intensity[1], 1001);
	d.resize(d.size() - 3);
	writeBytes(bpath, d);
	EXPECT_NE(expectThrowMessage([&] { readPly(bpath); }).find("truncated"),
	          std::string::npos);

	writeBytes(bpath, std::vector<char>{'p', 'l', 'x', '\n'});
	EXPECT_NE(expectThrowMessage([&] { readPly(bpath); }).find("signature"),
	          std::string::npos);
	EXPECT_THROW(readCloudFile(tmpPath("x.xyz")), CloudFileError);
}
