// Organizing ring-tagged points into a CObservationRotatingScan that
// core::unpackRotatingScan reads back: exact round trip of a range image,
// ring order detection, errors.
#include <forest_slam/core/lidar_model.h>
#include <forest_slam/core/scan_points.h>
#include <forest_slam/ingest/scan_organizer.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>

using namespace forest_slam;
using namespace forest_slam::ingest;

namespace
{
constexpr int64_t kStampNs = 1700000000000000000LL;

/** A VLP-16 revolution as the simulator builds it: clockwise, n columns
 * over 2*pi*(n-1)/n, some cells empty. */
mrpt::obs::CObservationRotatingScan syntheticScan(int n = 1800)
{
	mrpt::obs::CObservationRotatingScan s;
	s.rowCount = 16;
	s.columnCount = static_cast<uint16_t>(n);
	s.lidarModel = "VLP16";
	s.rangeResolution = 0.002;
	s.startAzimuth = M_PI;
	s.azimuthSpan = -2 * M_PI * (n - 1) / n;
	s.sweepDuration = 0.1 * (n - 1) / n;
	s.minRange = 0.5;
	s.maxRange = 100;
	s.timestamp = mrpt::Clock::fromDouble(kStampNs * 1e-9);
	s.rangeImage.setZero(16, n);
	s.intensityImage.setZero(16, n);
	for (int r = 0; r < 16; r++)
		for (int c = 0; c < n; c++)
		{
			// Holes (sky, absorbers) in a third of the cells; none in the
			// first and last column so the grid ends are observed.
			if (c > 0 && c < n - 1 && ((r * 7 + c * 13) % 3 == 0)) continue;
			const double range =
			    3.0 + 20.0 * (0.5 + 0.5 * std::sin(c * 0.01 + r));
			s.rangeImage(r, c) =
			    static_cast<uint16_t>(std::lround(range / 0.002));
			s.intensityImage(r, c) = static_cast<uint8_t>((r * 16 + c) % 256);
		}
	return s;
}

std::vector<CloudPoint> toCloud(const core::ScanPoints& sp,
                                const std::vector<int>& ring_of_row)
{
	std::vector<CloudPoint> out;
	for (const auto& p : sp.points)
	{
		CloudPoint q;
		q.x = p.x;
		q.y = p.y;
		q.z = p.z;
		q.intensity = p.intensity;
		q.ring = static_cast<uint16_t>(ring_of_row[p.ring]);
		q.t_s = p.t_s;
		out.push_back(q);
	}
	return out;
}

void expectSamePoints(const core::ScanPoints& a, const core::ScanPoints& b)
{
	ASSERT_EQ(a.points.size(), b.points.size());
	// Both are ordered by column then row.
	double max_d = 0, max_dt = 0;
	for (size_t i = 0; i < a.points.size(); i++)
	{
		const auto &p = a.points[i], &q = b.points[i];
		ASSERT_EQ(p.ring, q.ring) << i;
		max_d = std::max({max_d, double(std::abs(p.x - q.x)),
		                  double(std::abs(p.y - q.y)),
		                  double(std::abs(p.z - q.z))});
		max_dt = std::max(max_dt,
		                  std::abs((a.stamp_s + p.t_s) - (b.stamp_s + q.t_s)));
		EXPECT_EQ(p.intensity, q.intensity);
	}
	EXPECT_LT(max_d, 2e-5) << "points differ beyond float precision";
	EXPECT_LT(max_dt, 1e-6);
}
}  // namespace

TEST(IngestOrganizer, RangeImageRoundTripIsExact)
{
	const auto scan = syntheticScan();
	const auto sp = core::unpackRotatingScan(scan);
	std::vector<int> identity(16);
	for (int i = 0; i < 16; i++) identity[i] = i;
	OrganizerOptions o;
	o.lidar_model = "VLP16";
	ScanOrganizer org(o);
	mrpt::obs::CObservationRotatingScan out;
	OrganizeStats st;
	org.organize(toCloud(sp, identity), kStampNs, true, out, &st);
	EXPECT_EQ(org.ringOrder(), RingOrder::Native);
	EXPECT_EQ(out.columnCount, scan.columnCount);
	EXPECT_EQ(st.collisions, 0u);
	EXPECT_EQ(st.out_of_range, 0u);
	EXPECT_LT(st.max_time_error_s, 1e-6);
	EXPECT_NEAR(out.sweepDuration, scan.sweepDuration, 1e-9);
	EXPECT_LT(std::abs(out.azimuthSpan - scan.azimuthSpan), 1e-6);
	for (int r = 0; r < 16; r++)
		for (int c = 0; c < scan.columnCount; c++)
			ASSERT_EQ(out.rangeImage(r, c), scan.rangeImage(r, c))
			    << r << "," << c;
	expectSamePoints(sp, core::unpackRotatingScan(out));
}

TEST(IngestOrganizer, RingOrderDetectedFromElevations)
{
	const auto scan = syntheticScan(900);
	const auto sp = core::unpackRotatingScan(scan);
	const auto& model = core::lidarModelByName("VLP16");
	const auto by_el = model.rowsByElevation();
	std::vector<int> asc(16), desc(16);
	for (int k = 0; k < 16; k++)
	{
		asc[by_el[k]] = k;  // ring k = k-th lowest beam (ROS velodyne driver)
		desc[by_el[k]] = 15 - k;
	}
	for (const auto& [order, map] :
	     {std::make_pair(RingOrder::ElevationAscending, asc),
	      std::make_pair(RingOrder::ElevationDescending, desc)})
	{
		ScanOrganizer org(OrganizerOptions{});
		mrpt::obs::CObservationRotatingScan out;
		org.organize(toCloud(sp, map), kStampNs, true, out);
		EXPECT_EQ(org.ringOrder(), order);
		expectSamePoints(sp, core::unpackRotatingScan(out));
	}
}

TEST(IngestOrganizer, CloudWithoutTimesUsesFiringOrder)
{
	const auto scan = syntheticScan(900);
	const auto sp = core::unpackRotatingScan(scan);
	std::vector<int> identity(16);
	for (int i = 0; i < 16; i++) identity[i] = i;
	auto cloud = toCloud(sp, identity);
	for (auto& p : cloud) p.t_s = 0;
	OrganizerOptions o;
	o.rate_hz = 10;
	ScanOrganizer org(o);
	mrpt::obs::CObservationRotatingScan out;
	org.organize(cloud, kStampNs, false, out);
	ASSERT_EQ(out.columnCount, scan.columnCount);
	for (int r = 0; r < 16; r++)
		for (int c = 0; c < scan.columnCount; c++)
			ASSERT_EQ(out.rangeImage(r, c), scan.rangeImage(r, c));
	// Timing from the nominal rate: 900 columns of 0.4 deg at 10 Hz.
	EXPECT_NEAR(out.sweepDuration, 0.1 * 899 / 900, 1e-6);
	EXPECT_LT(out.azimuthSpan, 0) << "clockwise from the firing order";
}

TEST(IngestOrganizer, WrongModelOrRingIsAnError)
{
	const auto scan = syntheticScan(600);
	const auto sp = core::unpackRotatingScan(scan);
	std::vector<int> identity(16);
	for (int i = 0; i < 16; i++) identity[i] = i;
	auto cloud = toCloud(sp, identity);
	OrganizerOptions o;
	o.lidar_model = "HDL32";  // 32 rings over -30..+10 deg
	ScanOrganizer org(o);
	mrpt::obs::CObservationRotatingScan out;
	try
	{
		org.organize(cloud, kStampNs, true, out);
		FAIL() << "VLP-16 elevations accepted as HDL-32";
	}
	catch (const std::runtime_error& e)
	{
		EXPECT_NE(std::string(e.what()).find("HDL32"), std::string::npos)
		    << e.what();
	}
	cloud[5].ring = 16;
	ScanOrganizer org16(OrganizerOptions{});
	EXPECT_THROW(org16.organize(cloud, kStampNs, true, out),
	             std::runtime_error);
}

TEST(IngestOrganizer, EmptyCloudGivesEmptyScan)
{
	ScanOrganizer org(OrganizerOptions{});
	mrpt::obs::CObservationRotatingScan out;
	org.organize({}, kStampNs, true, out);
	EXPECT_EQ(out.columnCount, 0);
	EXPECT_TRUE(core::unpackRotatingScan(out).points.empty());
}
