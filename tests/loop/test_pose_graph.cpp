#include "synthetic_forest.h"

#include <forest_slam/loop/pose_graph.h>
#include <forest_slam/loop/relative_pose_cost.h>

#include <ceres/autodiff_cost_function.h>
#include <gtest/gtest.h>

#include <array>
#include <random>

using namespace forest_slam::loop;
using namespace forest_slam::loop::test;

namespace
{
/** A closed square path of 4 x n unit steps, true poses. */
std::vector<Eigen::Isometry3d> square(int n)
{
	std::vector<Eigen::Isometry3d> p;
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	for (int side = 0; side < 4; side++)
		for (int i = 0; i < n; i++)
		{
			p.push_back(T);
			Eigen::Isometry3d step = poseXYZYaw(1, 0, 0, i + 1 == n ? 90 : 0);
			T = T * step;
		}
	p.push_back(T);  // back at the start
	return p;
}
}  // namespace

// The closed-form Jacobians against automatic derivatives of the same
// residual, projected onto the quaternions' tangent space (what Ceres uses),
// at random poses, measurements and a full sqrt-information matrix.
TEST(PoseGraph, AnalyticJacobiansMatchAutomaticDerivatives)
{
	std::mt19937 rng(7);
	std::normal_distribution<double> n(0, 1);
	auto quat = [&]
	{ return Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized(); };
	auto vec = [&] { return Eigen::Vector3d(n(rng), n(rng), n(rng)); };
	for (int trial = 0; trial < 20; trial++)
	{
		Eigen::Quaterniond qa = quat(), qb = quat();
		const Eigen::Quaterniond qab = quat();
		Eigen::Vector3d pa = 10 * vec(), pb = 10 * vec();
		const Eigen::Vector3d pab = vec();
		Matrix6d S = Matrix6d::Identity() * 50;
		for (int i = 0; i < 6; i++)
			for (int j = i + 1; j < 6; j++) S(i, j) = 5 * n(rng);
		ceres::AutoDiffCostFunction<RelativePoseError, 6, 3, 4, 3, 4> reference(
		    new RelativePoseError{pab, qab, S});
		const RelativePoseCost analytic(pab, qab, S);
		const double* x[4] = {pa.data(), qa.coeffs().data(), pb.data(),
		                      qb.coeffs().data()};
		double r_ref[6], r[6];
		std::array<std::array<double, 24>, 4> J_ref{}, J{};
		double* j_ref[4] = {J_ref[0].data(), J_ref[1].data(), J_ref[2].data(),
		                    J_ref[3].data()};
		double* j[4] = {J[0].data(), J[1].data(), J[2].data(), J[3].data()};
		ASSERT_TRUE(reference.Evaluate(x, r_ref, j_ref));
		ASSERT_TRUE(analytic.Evaluate(x, r, j));
		for (int i = 0; i < 6; i++) EXPECT_NEAR(r[i], r_ref[i], 1e-9);
		for (int b = 0; b < 4; b++)
		{
			using J6x3 = Eigen::Matrix<double, 6, 3, Eigen::RowMajor>;
			using J6x4 = Eigen::Matrix<double, 6, 4, Eigen::RowMajor>;
			J6x3 tangent_ref, tangent;
			if (b % 2 == 0)
			{
				tangent_ref = Eigen::Map<J6x3>(J_ref[b].data());
				tangent = Eigen::Map<J6x3>(J[b].data());
			}
			else
			{
				Eigen::Matrix<double, 4, 3, Eigen::RowMajor> P;
				ceres::EigenQuaternionManifold().PlusJacobian(x[b], P.data());
				tangent_ref = Eigen::Map<J6x4>(J_ref[b].data()) * P;
				tangent = Eigen::Map<J6x4>(J[b].data()) * P;
			}
			EXPECT_LT((tangent - tangent_ref).cwiseAbs().maxCoeff(),
			          1e-9 * (1 + tangent_ref.cwiseAbs().maxCoeff()))
			    << "trial " << trial << " block " << b << "\n"
			    << tangent << "\nautomatic:\n"
			    << tangent_ref;
			EXPECT_GT(tangent_ref.cwiseAbs().maxCoeff(), 1e-3)
			    << "block " << b;  // the check is not vacuous
		}
		// Only-residual evaluations agree too (Ceres asks for those).
		ASSERT_TRUE(analytic.Evaluate(x, r, nullptr));
		for (int i = 0; i < 6; i++) EXPECT_NEAR(r[i], r_ref[i], 1e-9);
	}
}

TEST(PoseGraph, LoopFactorRemovesYawDrift)
{
	const auto truth = square(10);
	PoseGraph g;
	// Odometry with 0.2 deg of yaw error per step.
	const Eigen::Isometry3d bias = poseXYZYaw(0, 0, 0.002, 0.3);
	Eigen::Isometry3d T = truth[0];
	g.addNode(T);
	for (size_t i = 1; i < truth.size(); i++)
	{
		const Eigen::Isometry3d edge = truth[i - 1].inverse() * truth[i] * bias;
		T = T * edge;
		g.addNode(T);
		RelativeFactor f;
		f.a = i - 1;
		f.b = i;
		f.T_ab = edge;
		f.sqrt_information = sqrtInformation(0.02, 0.1 * M_PI / 180);
		g.addFactor(f);
	}
	const double before =
	    (g.pose(truth.size() - 1).translation() - truth.back().translation())
	        .norm();
	EXPECT_GT(before, 1.0);
	RelativeFactor loop;
	loop.a = 0;
	loop.b = truth.size() - 1;
	loop.T_ab = truth[0].inverse() * truth.back();
	loop.sqrt_information = sqrtInformation(0.01, 0.05 * M_PI / 180);
	g.addFactor(loop);
	ASSERT_TRUE(g.optimize(10, 4));
	double worst = 0;
	for (size_t i = 0; i < truth.size(); i++)
		worst = std::max(
		    worst, (g.pose(i).translation() - truth[i].translation()).norm());
	EXPECT_LT(
	    (g.pose(truth.size() - 1).translation() - truth.back().translation())
	        .norm(),
	    0.05);
	EXPECT_LT(worst, 0.6);  // the error is spread, not gone
	EXPECT_FALSE(g.hasEnu());
}

TEST(PoseGraph, GnssTiesTheMapToEnuAndDropsAJump)
{
	// A straight 60 m walk with odometry that under-reports 2 % of the
	// distance; fixes every 5 m in an ENU frame rotated 30 deg, one of them
	// 50 m off (sigma 0.5 m claimed).
	PoseGraph g;
	const int n = 61;
	const MapToEnu truth_enu{30 * M_PI / 180, Eigen::Vector3d(100, -50, 3)};
	for (int i = 0; i < n; i++)
	{
		g.addNode(poseXYZYaw(0.98 * i, 0, 0, 0));
		if (i > 0)
		{
			RelativeFactor f;
			f.a = i - 1;
			f.b = i;
			f.T_ab = poseXYZYaw(0.98, 0, 0, 0);
			f.sqrt_information = sqrtInformation(0.05, 0.1 * M_PI / 180);
			g.addFactor(f);
		}
		if (i % 5 == 0)
		{
			GnssFactor gf;
			gf.node = i;
			gf.antenna_in_node = Eigen::Vector3d(0, 0, 0.3);
			gf.enu = truth_enu.apply(Eigen::Vector3d(i, 0, 0.3));
			if (i == 30) gf.enu.x() += 50;
			gf.sigma = Eigen::Vector3d(0.5, 0.5, 0.8);
			g.addGnss(gf);
		}
	}
	ASSERT_TRUE(g.optimize(15, 4));
	ASSERT_TRUE(g.hasEnu());
	EXPECT_NEAR(g.mapToEnu().yaw, truth_enu.yaw, 0.01);
	int outliers = 0;
	for (const auto& f : g.gnss()) outliers += f.outlier;
	EXPECT_EQ(outliers, 1);
	EXPECT_TRUE(g.gnss()[6].outlier);  // node 30
	// The fixes pull the under-reported distance back (the odometry alone
	// ends 1.2 m short); the outlier does not pull node 30 aside.
	EXPECT_NEAR(g.pose(n - 1).translation().x(), n - 1, 0.8);
	EXPECT_NEAR(g.pose(30).translation().y(), 0, 0.05);
	EXPECT_NEAR(g.pose(30).translation().x(), 30, 0.5);
}
