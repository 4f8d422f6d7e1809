// PointCloud2 layouts of the common drivers: fields found, per-point time
// converted to seconds after the header stamp, damage reported by name.
#include <forest_slam/ingest/pointcloud2.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>

using namespace forest_slam::ingest;

namespace
{
struct FieldSpec
{
	const char* name;
	uint8_t type;
};

size_t typeSize(uint8_t t)
{
	return t <= 2 ? 1 : t <= 4 ? 2 : t <= 7 ? 4 : 8;
}

/** A cloud with the given fields packed in order; values[i][f] as double. */
PointCloud2Msg makeCloud(const std::vector<FieldSpec>& spec,
                         const std::vector<std::vector<double>>& values,
                         int64_t stamp_ns, bool big_endian = false)
{
	PointCloud2Msg m;
	m.header.stamp_ns = stamp_ns;
	uint32_t off = 0;
	for (const auto& f : spec)
	{
		m.fields.push_back({f.name, off, f.type, 1});
		off += static_cast<uint32_t>(typeSize(f.type));
	}
	m.point_step = off + 2;  // drivers pad: keep a gap to test offsets
	m.height = 1;
	m.width = static_cast<uint32_t>(values.size());
	m.row_step = m.point_step * m.width;
	m.is_bigendian = big_endian;
	m.data.assign(m.row_step, 0xAB);
	for (size_t i = 0; i < values.size(); i++)
		for (size_t j = 0; j < spec.size(); j++)
		{
			uint8_t* p = m.data.data() + i * m.point_step + m.fields[j].offset;
			const double v = values[i][j];
			uint8_t b[8];
			size_t n = typeSize(spec[j].type);
			switch (spec[j].type)
			{
				case 2:
					b[0] = static_cast<uint8_t>(v);
					break;
				case 4:
				{
					uint16_t x = static_cast<uint16_t>(v);
					std::memcpy(b, &x, 2);
					break;
				}
				case 6:
				{
					uint32_t x = static_cast<uint32_t>(v);
					std::memcpy(b, &x, 4);
					break;
				}
				case 7:
				{
					float x = static_cast<float>(v);
					std::memcpy(b, &x, 4);
					break;
				}
				case 8:
					std::memcpy(b, &v, 8);
					break;
				default:
					ADD_FAILURE() << "type not used in tests";
			}
			if (big_endian) std::reverse(b, b + n);
			std::memcpy(p, b, n);
		}
	return m;
}
constexpr int64_t kStamp = 1700000000500000000LL;
}  // namespace

TEST(IngestPointCloud2, VelodyneDriverLayout)
{
	const auto m =
	    makeCloud({{"x", 7},
	               {"y", 7},
	               {"z", 7},
	               {"intensity", 7},
	               {"ring", 4},
	               {"time", 7}},
	              {{1, 2, 3, 40, 5, 0.01}, {4, 5, 6, 50, 15, 0.0995}}, kStamp);
	const auto L = analyzeCloudLayout(m, {});
	EXPECT_TRUE(L.ring.present);
	EXPECT_EQ(L.ring.name, "ring");
	EXPECT_EQ(L.time.name, "time");
	EXPECT_EQ(L.time_encoding, TimeEncoding::RelativeSeconds);
	std::vector<CloudPoint> pts;
	EXPECT_EQ(extractCloudPoints(m, L, pts), 0u);
	ASSERT_EQ(pts.size(), 2u);
	EXPECT_FLOAT_EQ(pts[1].x, 4);
	EXPECT_FLOAT_EQ(pts[1].intensity, 50);
	EXPECT_EQ(pts[1].ring, 15);
	EXPECT_NEAR(pts[1].t_s, 0.0995, 1e-7);
}

TEST(IngestPointCloud2, OusterLayoutUint8RingNanosecondTime)
{
	const auto m =
	    makeCloud({{"x", 7},
	               {"y", 7},
	               {"z", 7},
	               {"t", 6},
	               {"reflectivity", 4},
	               {"ring", 2}},
	              {{1, 0, 0, 0, 100, 0}, {0, 2, 0, 48828125, 200, 63}}, kStamp);
	const auto L = analyzeCloudLayout(m, {});
	EXPECT_EQ(L.time.name, "t");
	EXPECT_EQ(L.intensity.name, "reflectivity");
	std::vector<CloudPoint> pts;
	extractCloudPoints(m, L, pts);
	ASSERT_EQ(pts.size(), 2u);
	EXPECT_EQ(pts[1].ring, 63);
	EXPECT_NEAR(pts[1].t_s, 0.048828125, 1e-12);
	EXPECT_FLOAT_EQ(pts[1].intensity, 200);
}

TEST(IngestPointCloud2, HesaiAbsoluteSecondsBecomeRelative)
{
	const double stamp_s = kStamp * 1e-9;
	const auto m = makeCloud(
	    {{"x", 7},
	     {"y", 7},
	     {"z", 7},
	     {"intensity", 7},
	     {"timestamp", 8},
	     {"ring", 4}},
	    {{1, 1, 1, 9, stamp_s + 0.001, 3}, {2, 2, 2, 9, stamp_s + 0.0625, 31}},
	    kStamp);
	const auto L = analyzeCloudLayout(m, {});
	std::vector<CloudPoint> pts;
	extractCloudPoints(m, L, pts);
	ASSERT_EQ(pts.size(), 2u);
	// float64 UNIX seconds resolve to ~0.2 us.
	EXPECT_NEAR(pts[0].t_s, 0.001, 1e-6);
	EXPECT_NEAR(pts[1].t_s, 0.0625, 1e-6);
	// Declared explicitly, the same numbers are not reinterpreted.
	CloudLayoutOptions o;
	o.time_encoding = "relative_s";
	const auto L2 = analyzeCloudLayout(m, o);
	extractCloudPoints(m, L2, pts);
	EXPECT_GT(pts[0].t_s, 1e9);
}

TEST(IngestPointCloud2, InvalidPointsAreDroppedAndCounted)
{
	const double nan = std::nan("");
	const auto m =
	    makeCloud({{"x", 7}, {"y", 7}, {"z", 7}},
	              {{1, 2, 3}, {nan, 0, 0}, {0, 0, 0}, {4, 5, 6}}, kStamp);
	const auto L = analyzeCloudLayout(m, {});
	EXPECT_FALSE(L.ring.present);
	EXPECT_FALSE(L.time.present);
	std::vector<CloudPoint> pts;
	EXPECT_EQ(extractCloudPoints(m, L, pts), 2u);
	EXPECT_EQ(pts.size(), 2u);
}

TEST(IngestPointCloud2, BigEndianClouds)
{
	const auto m =
	    makeCloud({{"x", 7}, {"y", 7}, {"z", 7}, {"ring", 4}, {"time", 7}},
	              {{1.5, -2.25, 3, 7, 0.05}}, kStamp, true);
	const auto L = analyzeCloudLayout(m, {});
	std::vector<CloudPoint> pts;
	extractCloudPoints(m, L, pts);
	ASSERT_EQ(pts.size(), 1u);
	EXPECT_FLOAT_EQ(pts[0].y, -2.25f);
	EXPECT_EQ(pts[0].ring, 7);
	EXPECT_NEAR(pts[0].t_s, 0.05, 1e-7);
}

TEST(IngestPointCloud2, DamageIsNamed)
{
	auto m =
	    makeCloud({{"x", 7}, {"y", 7}, {"intensity", 7}}, {{1, 2, 3}}, kStamp);
	try
	{
		analyzeCloudLayout(m, {});
		FAIL();
	}
	catch (const DecodeError& e)
	{
		EXPECT_NE(std::string(e.what()).find("x/y/z"), std::string::npos)
		    << e.what();
		EXPECT_NE(std::string(e.what()).find("intensity"), std::string::npos)
		    << e.what();
	}
	auto m2 = makeCloud({{"x", 7}, {"y", 7}, {"z", 7}}, {{1, 2, 3}, {4, 5, 6}},
	                    kStamp);
	m2.fields[2].offset = m2.point_step;  // beyond the point
	EXPECT_THROW(analyzeCloudLayout(m2, {}), DecodeError);
	auto m3 = makeCloud({{"x", 7}, {"y", 7}, {"z", 7}}, {{1, 2, 3}, {4, 5, 6}},
	                    kStamp);
	m3.data.resize(m3.data.size() - 1);
	const auto L3 = analyzeCloudLayout(m3, {});
	std::vector<CloudPoint> pts;
	EXPECT_THROW(extractCloudPoints(m3, L3, pts), DecodeError);
	CloudLayoutOptions o;
	o.ring_field = "laser_number";
	EXPECT_THROW(analyzeCloudLayout(m3, o), DecodeError);
}
