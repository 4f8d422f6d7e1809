#include <forest_slam/core/lidar_model.h>
#include <forest_slam/core/scan_points.h>
#include <gtest/gtest.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/system/datetime.h>

#include <cmath>

using namespace forest_slam::core;

TEST(LidarModel, Vlp16TableAndAliases)
{
	const auto& m = lidarModelByName("VLP-16");
	ASSERT_EQ(m.rings(), 16u);
	EXPECT_NEAR(m.elevation_rad[0], -15 * M_PI / 180, 1e-12);
	EXPECT_NEAR(m.elevation_rad[1], 1 * M_PI / 180, 1e-12);
	EXPECT_NEAR(m.elevation_rad[15], 15 * M_PI / 180, 1e-12);
	const auto order = m.rowsByElevation();
	EXPECT_EQ(order.front(), 0);
	EXPECT_EQ(order.back(), 15);
	EXPECT_EQ(&lidarModelByName("vlp16"), &m);
	EXPECT_EQ(lidarModelByName("HDL-32E").rings(), 32u);
	EXPECT_EQ(lidarModelByName("OS1-64").rings(), 64u);
	EXPECT_THROW(lidarModelByName("XYZ"), std::invalid_argument);
}

namespace
{
mrpt::obs::CObservationRotatingScan makeScan(int cols)
{
	mrpt::obs::CObservationRotatingScan s;
	s.lidarModel = "VLP16";
	s.rowCount = 16;
	s.columnCount = cols;
	s.rangeImage.setZero(16, cols);
	s.intensityImage.setZero(16, cols);
	s.rangeResolution = 0.01;
	s.startAzimuth = 0;
	s.azimuthSpan = M_PI;  // half a turn over the columns
	s.sweepDuration = 0.05;
	s.minRange = 0.5;
	s.maxRange = 100;
	s.timestamp = mrpt::Clock::fromDouble(1000.0);
	return s;
}
}  // namespace

TEST(ScanPoints, GeometryTimingAndLayers)
{
	auto s = makeScan(3);
	s.rangeImage(0, 0) = 1000;	// 10 m, ring 0 (-15 deg), azimuth 0
	s.rangeImage(1, 1) = 500;  // 5 m, ring 1 (+1 deg), azimuth pi/2
	s.rangeImage(15, 2) = 20;  // 0.2 m < minRange: dropped
	s.intensityImage(0, 0) = 77;
	mrpt::math::CMatrix_u16 lab(16, 3);
	lab.setZero();
	lab(0, 0) = 2;
	lab(1, 1) = 1;
	s.rangeOtherLayers["gt_label"] = lab;

	const auto pts = unpackRotatingScan(s);
	ASSERT_EQ(pts.points.size(), 2u);
	EXPECT_DOUBLE_EQ(pts.stamp_s, 1000.0);
	const auto& a = pts.points[0];
	EXPECT_NEAR(a.x, 10 * std::cos(-15 * M_PI / 180), 1e-4);
	EXPECT_NEAR(a.y, 0, 1e-4);
	EXPECT_NEAR(a.z, 10 * std::sin(-15 * M_PI / 180), 1e-4);
	EXPECT_FLOAT_EQ(a.intensity, 77);
	EXPECT_FLOAT_EQ(a.t_s, 0);
	const auto& b = pts.points[1];
	EXPECT_NEAR(b.x, 0, 1e-4);
	EXPECT_NEAR(b.y, 5 * std::cos(M_PI / 180), 1e-4);
	EXPECT_NEAR(b.t_s, 0.025, 1e-6);
	EXPECT_EQ(b.ring, 1);
	EXPECT_EQ(b.column, 1);
	const auto* l = pts.layer("gt_label");
	ASSERT_NE(l, nullptr);
	EXPECT_EQ((*l)[0], 2);
	EXPECT_EQ((*l)[1], 1);
}

TEST(ScanPoints, RejectsInconsistentScans)
{
	auto s = makeScan(4);
	s.lidarModel = "HDL32";
	EXPECT_THROW(unpackRotatingScan(s), std::invalid_argument);
	auto t = makeScan(4);
	t.columnCount = 5;	// header disagrees with the image
	EXPECT_THROW(unpackRotatingScan(t), std::invalid_argument);
	auto u = makeScan(4);
	u.lidarModel = "NOPE";
	EXPECT_THROW(unpackRotatingScan(u), std::invalid_argument);
}
