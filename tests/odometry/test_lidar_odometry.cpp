#include "../pipeline/synthetic_scans.h"

#include <forest_slam/odometry/lidar_odometry.h>
#include <gtest/gtest.h>

#include <cstdio>

using namespace forest_slam;

TEST(LidarOdometry, FollowsConstantVelocityMotion)
{
	test_support::MovingSensorWorld w;
	// A stand of poles on both sides: with only the default five, nothing
	// but their silhouettes holds the pose across the motion (y).
	w.poles = {{5, 4}, {-6, -5}, {8, -6}, {-3, 6}, {2, -4}, {3, 3},  {-1, -3},
	           {6, 2}, {9, 5},   {-4, 3}, {1, 5},  {4, -2}, {7, -3}, {10, -4}};
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
