#include "../pipeline/synthetic_scans.h"

#include <forest_slam/core/config.h>
#include <forest_slam/imu/imu_buffer.h>
#include <forest_slam/odometry/lidar_odometry.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

using namespace forest_slam;

namespace
{
/** A stand of poles on both sides of the drive: with only the world's
 * default five, nothing but their silhouettes holds the pose across the
 * motion (y). */
std::vector<Eigen::Vector2d> standOfPoles()
{
	return {{5, 4}, {-6, -5}, {8, -6}, {-3, 6}, {2, -4}, {3, 3},  {-1, -3},
	        {6, 2}, {9, 5},   {-4, 3}, {1, 5},  {4, -2}, {7, -3}, {10, -4}};
}
}  // namespace

TEST(LidarOdometry, FollowsConstantVelocityMotion)
{
	test_support::MovingSensorWorld w;
	w.poles = standOfPoles();
	map::CForestMap m;
	odometry::OdometryConfig cfg;
	odometry::LidarOdometry od(cfg, m);
	double worst = 0;
	for (int k = 0; k < 20; k++)
	{
		const auto st = od.processScan(core::unpackRotatingScan(w.scan(k)));
		const auto t = st.pose.pose.translation();
		const double err = (t - w.positionAt(w.t0_s + k * w.period_s)).norm();
		worst = std::max(worst, err);
		if (getenv("FS_DEBUG"))
		{
			std::printf(
			    "k=%d edges=%zu planar=%zu reg=%d em=%zu pm=%zu it=%d "
			    "rmse=%.3f t=(%.3f %.3f %.3f) ev0=%.2g ev5=%.2g err=%.3f\n",
			    k, st.edges, st.planar, st.registered,
			    st.registration.edge_matches, st.registration.planar_matches,
			    st.registration.iterations, st.registration.rmse_m, t.x(),
			    t.y(), t.z(), st.registration.information_eigenvalues[0],
			    st.registration.information_eigenvalues[5], err);
		}
		if (k > 0)
		{
			EXPECT_TRUE(st.registered) << "scan " << k;
		}
	}
	// 3.8 m travelled without IMU: a few centimetres, set while the map is
	// young; it must not grow.
	EXPECT_LT(worst, 0.08);
}

namespace
{
/** The CForestMap's voxels after each of 20 scans of the poles world, and
 * the worst position error, with every other scan inserted whole and the
 * others from far_m on. */
std::vector<size_t> voxelsAlongTheDrive(double far_m, double& worst)
{
	test_support::MovingSensorWorld w;  // 2 m/s: 0.2 m from scan to scan
	w.poles = standOfPoles();
	map::CForestMap m;
	odometry::OdometryConfig cfg;
	cfg.odometry.map_insert_every_scans = 2;
	cfg.odometry.map_insert_far_m = far_m;
	cfg.odometry.start_radius_m = 1.0;  // left at scan 5
	odometry::LidarOdometry od(cfg, m);
	std::vector<size_t> voxels;
	worst = 0;
	for (int k = 0; k < 20; k++)
	{
		const auto st = od.processScan(core::unpackRotatingScan(w.scan(k)));
		od.flushMap();
		voxels.push_back(m.edgePointCount() + m.planarPointCount());
		if (k > 0)
		{
			EXPECT_TRUE(st.registered) << "scan " << k;
		}
		worst = std::max(worst, (st.pose.pose.translation() -
		                         w.positionAt(w.t0_s + k * w.period_s))
		                            .norm());
	}
	return voxels;
}
}  // namespace

TEST(LidarOdometry, MapInsertEveryOtherScanAfterTheStart)
{
	double worst = 0;
	const auto voxels = voxelsAlongTheDrive(0, worst);
	for (int k = 2; k < 20; k++)
	{
		// Within the start every scan adds voxels (scan 1 rebuilds the map
		// from scan 0 deskewed with the motion now known); after it, odd
		// scans are registered but leave the map as it was.
		if (k < 5 || k % 2 == 0)
		{
			EXPECT_GT(voxels[k], voxels[k - 1]) << "scan " << k;
		}
		else if (k > 5)
		{
			EXPECT_EQ(voxels[k], voxels[k - 1]) << "scan " << k;
		}
	}
	EXPECT_LT(worst, 0.08);  // as with every scan inserted
	// With the odd scans' points from 1 m on (nearly all), they add voxels
	// too.
	const auto far = voxelsAlongTheDrive(1.0, worst);
	for (int k = 7; k < 20; k += 2)
		EXPECT_GT(far[k], far[k - 1]) << "scan " << k;
	EXPECT_LT(worst, 0.08);
}

namespace
{
double yawDeg(const Eigen::Isometry3d& T)
{
	return std::atan2(T.linear()(1, 0), T.linear()(0, 0)) * 180 / M_PI;
}

/** Yaw of each of the first `scans` poses of the poles world (a straight
 * drive at 2 m/s) with an IMU whose gyro says the rig turns at 0.5 deg/s
 * while it does not, under the given start prior. */
std::vector<double> yawWithAWrongGyro(double start_sigma_deg,
                                      double start_radius_m, int scans)
{
	test_support::MovingSensorWorld w;
	w.poles = standOfPoles();
	imu::ImuBuffer imu;
	const double rate = 0.5 * M_PI / 180;
	for (double t = w.t0_s - 1; t < w.t0_s + (scans + 1) * w.period_s;
	     t += 0.005)
		EXPECT_TRUE(imu.add(t, {0, 0, rate}, {0, 0, 9.80665}));
	map::CForestMap m;
	odometry::OdometryConfig cfg;
	cfg.odometry.start_rotation_sigma_deg = start_sigma_deg;
	cfg.odometry.start_radius_m = start_radius_m;
	odometry::LidarOdometry od(cfg, m);
	od.setImu(&imu, Eigen::Matrix3d::Identity());
	std::vector<double> yaw;
	for (int k = 0; k < scans; k++)
	{
		const auto st = od.processScan(core::unpackRotatingScan(w.scan(k)));
		EXPECT_TRUE(st.imu_used) << "scan " << k;
		yaw.push_back(yawDeg(st.pose.pose));
	}
	return yaw;
}
}  // namespace

TEST(LidarOdometry, StartPriorHoldsTheGyroOnlyWithinTheStartRadius)
{
	const auto off = yawWithAWrongGyro(0, 2.0, 20);
	const auto on = yawWithAWrongGyro(0.001, 2.0, 20);
	const auto zero = yawWithAWrongGyro(0.001, 0, 20);
	if (getenv("FS_DEBUG"))
		for (size_t k = 0; k < off.size(); k++)
			std::printf("k=%zu off %.3f on %.3f zero %.3f\n", k, off[k], on[k],
			            zero[k]);
	// On: within the first 2 m (10 scans at 2 m/s) the rotation is the
	// gyro's, 0.05 deg per scan, the bootstrap's second scan included.
	for (int k = 1; k <= 10; k++)
		EXPECT_NEAR(on[k], 0.05 * k, 0.01) << "scan " << k;
	// Once the lidar has left, the registration holds the map's yaw (the
	// map keeps what the start put in it) and no longer follows the gyro.
	EXPECT_LT(std::abs(on[19] - on[10]), 0.15)
	    << "the gyro's turn carried on past the start radius: " << on[19];
	EXPECT_GT(on[19], 0.3);
	// Off, or radius 0: the registration corrects the gyro scan by scan.
	// (Starting at 2 m/s, the bootstrap's second scan is 0.35 deg off in
	// this world; the gyro's 0.5 deg by scan 10 would be 0.45.)
	for (int k = 5; k < 20; k++)
	{
		EXPECT_LT(std::abs(off[k]), 0.15) << "scan " << k;
		EXPECT_LT(std::abs(zero[k]), 0.15) << "scan " << k;
	}
}

TEST(LidarOdometry, StartPriorKeysAreChecked)
{
	for (const char* bad :
	     {"start_rotation_sigma_deg = -0.1", "start_radius_m = -5",
	      "map_insert_every_scans = 0", "map_insert_far_m = -1",
	      "start_plane_spread_ratio = 1.5", "start_plane_spread_ratio = -1"})
	{
		auto cfg = core::TrackedConfig::fromText(
		    std::string("[odometry]\n") + bad + "\n", "o.ini");
		odometry::OdometryOptions o;
		try
		{
			o.loadFromConfigFile(cfg, "odometry");
			FAIL() << bad << " was accepted";
		}
		catch (const core::ConfigError& e)
		{
			const std::string what = e.what();
			const std::string key(bad, std::string(bad).find(' '));
			EXPECT_NE(what.find("o.ini"), std::string::npos) << what;
			EXPECT_NE(what.find(key), std::string::npos) << what;
		}
	}
	auto ok = core::TrackedConfig::fromText(
	    "[odometry]\nstart_rotation_sigma_deg = 0.1\nstart_radius_m = 5\n"
	    "start_plane_spread_ratio = 0.25\n",
	    "o.ini");
	odometry::OdometryOptions o;
	o.loadFromConfigFile(ok, "odometry");
	EXPECT_DOUBLE_EQ(o.start_rotation_sigma_deg, 0.1);
	EXPECT_DOUBLE_EQ(o.start_radius_m, 5.0);
	EXPECT_DOUBLE_EQ(o.start_plane_spread_ratio, 0.25);
}
