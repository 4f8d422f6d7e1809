#include "synthetic_forest.h"

#include <forest_slam/loop/icp.h>
#include <forest_slam/loop/keyframe_cloud.h>
#include <gtest/gtest.h>

using namespace forest_slam::loop;
using namespace forest_slam::loop::test;

namespace
{
double angleDeg(const Eigen::Matrix3d& R)
{
	return Eigen::AngleAxisd(R).angle() * 180 / M_PI;
}
}  // namespace

/** Two views of three stems 3.2 m apart and 25 deg turned: the target
 * cloud of view A, the source cloud of view B, and A^-1 B. */
class TwoViews : public ::testing::Test
{
   protected:
	const std::vector<Stem> stems = makeStems(3, 40);
	const Eigen::Isometry3d A = poseXYZYaw(0, 0, 1.5, 0);
	const Eigen::Isometry3d B = poseXYZYaw(3.0, 1.0, 1.6, 25);
	IcpTarget target{
	    withNormals(voxelFilter(sampleView(stems, A, 20, 0.1, 1), 0.25, 40))};
	const std::vector<Eigen::Vector3f> source =
	    voxelFilter(sampleView(stems, B, 20, 0.1, 2), 0.25, 40);
	const Eigen::Isometry3d truth = A.inverse() * B;
	/** 0.8 m and 3 deg off the truth. */
	const Eigen::Isometry3d off_guess = poseXYZYaw(0.5, -0.5, 0.3, 3) * truth;
};

TEST_F(TwoViews, IcpRecoversTheOffset)
{
	ASSERT_GT(target.size(), 1000u);
	const IcpResult r = target.align(source, off_guess, IcpOptions{});
	EXPECT_TRUE(r.converged);
	const Eigen::Isometry3d e = truth.inverse() * r.T;
	EXPECT_LT(e.translation().norm(), 0.03);
	EXPECT_LT(angleDeg(e.linear()), 0.2);
	EXPECT_GT(r.overlap, 0.6);
	EXPECT_LT(r.rmse_m, 0.03);
}

TEST_F(TwoViews, AWellSeededIcpSkipsTheShrinkingGates)
{
	// Seeded at the truth, the pose does not move at the first (widest)
	// gate: the alignment goes to the final gate at once and stops there,
	// instead of stepping through the 25 shrinking gates.
	const IcpResult seeded = target.align(source, truth, IcpOptions{});
	EXPECT_TRUE(seeded.converged);
	EXPECT_LE(seeded.iterations, 6);
	EXPECT_LT((truth.inverse() * seeded.T).translation().norm(), 0.03);
	// Seeded 0.8 m off, it still shrinks the gate on the way in.
	const IcpResult off = target.align(source, off_guess, IcpOptions{});
	EXPECT_TRUE(off.converged);
	EXPECT_GT(off.iterations, seeded.iterations);
	EXPECT_LT((truth.inverse() * off.T).translation().norm(), 0.03);
}

TEST(Icp, NormalsAreTheSameOnAnyNumberOfThreads)
{
	// Each point's normal is its own: shared out among threads, the cloud
	// (points, their order, the normals) is bit for bit the serial one.
	const auto stems = makeStems(4, 40);
	const auto pts = voxelFilter(
	    sampleView(stems, poseXYZYaw(0, 0, 1.5, 0), 20, 0.1, 3), 0.25, 40);
	const NormalCloud one = withNormals(pts, 10, 0.3, 1);
	ASSERT_GT(one.points.size(), 1000u);
	ASSERT_LT(one.points.size(), pts.size());  // some dropped (not planar)
	for (int threads : {2, 3})
	{
		const NormalCloud many = withNormals(pts, 10, 0.3, threads);
		EXPECT_TRUE(many.points == one.points) << threads << " threads";
		EXPECT_TRUE(many.normals == one.normals) << threads << " threads";
	}
}

TEST(Icp, VoxelFilterKeepsEachVoxelsCentroidWithinRange)
{
	std::vector<Eigen::Vector3f> p{{0.01f, 0.01f, 0.01f},
	                               {0.02f, 0.02f, 0.04f},
	                               {-0.01f, 0.01f, 0.01f},
	                               {50, 0, 0},
	                               {NAN, 0, 0}};
	const auto f = voxelFilter(p, 0.1, 40);
	ASSERT_EQ(f.size(), 2u);  // the negative-x point is another voxel
	EXPECT_FLOAT_EQ(f[0].x(), 0.015f);
	EXPECT_FLOAT_EQ(f[0].z(), 0.025f);
	EXPECT_FLOAT_EQ(f[1].x(), -0.01f);
}

TEST(Icp, VoxelFilterDoesNotShiftASweepAlongItsDirection)
{
	// A wall 5 m ahead, listed in firing order (the sweep runs along +y):
	// the first point of each voxel is where the sweep entered it, half a
	// voxel behind the rest on average; the centroids are not.
	std::vector<Eigen::Vector3f> wall;
	for (int row = 0; row < 16; row++)
		for (int i = 0; i < 400; i++)
			wall.emplace_back(5.0f, -2.0f + 0.01f * (i + 0.5f),
			                  -0.5f + 0.0625f * row);
	double mean_in = 0, mean_out = 0;
	for (const auto& q : wall) mean_in += q.y();
	mean_in /= wall.size();
	const auto f = voxelFilter(wall, 0.25, 40);
	ASSERT_EQ(f.size(), 16u * 4u);
	for (const auto& q : f) mean_out += q.y();
	mean_out /= f.size();
	EXPECT_NEAR(mean_out, mean_in, 0.005);
	for (const auto& q : f) EXPECT_FLOAT_EQ(q.x(), 5.0f);
}
