#include <forest_slam/eval/hungarian.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

using namespace forest_slam::eval;

namespace
{
double totalCost(const Eigen::MatrixXd& c, const std::vector<int>& a)
{
	double s = 0;
	for (size_t i = 0; i < a.size(); i++)
		if (a[i] >= 0) s += c(static_cast<Eigen::Index>(i), a[i]);
	return s;
}

/** Exhaustive optimum over all injective row->column maps (rows <= cols). */
double bruteForce(const Eigen::MatrixXd& c)
{
	std::vector<int> cols(c.cols());
	std::iota(cols.begin(), cols.end(), 0);
	double best = 1e300;
	do
	{
		double s = 0;
		for (Eigen::Index i = 0; i < c.rows(); i++) s += c(i, cols[i]);
		best = std::min(best, s);
	} while (std::next_permutation(cols.begin(), cols.end()));
	return best;
}
}  // namespace

TEST(Hungarian, Hand3x3)
{
	Eigen::MatrixXd c(3, 3);
	c << 4, 1, 3, 2, 0, 5, 3, 2, 2;
	// Optimum by hand: r0->c1 (1), r1->c0 (2), r2->c2 (2) = 5.
	EXPECT_EQ(hungarian(c), (std::vector<int>{1, 0, 2}));

	Eigen::MatrixXd d(3, 3);
	d << 1, 2, 3, 2, 4, 6, 3, 6, 9;
	// Of the 6 permutations the anti-diagonal 3 + 4 + 3 = 10 is the minimum.
	EXPECT_EQ(hungarian(d), (std::vector<int>{2, 1, 0}));
	EXPECT_DOUBLE_EQ(totalCost(d, hungarian(d)), 10);

	// Greedy (smallest entry first: 0 at r0c0) would give 0 + 9 + 9 = 18;
	// the optimum is 1 + 1 + 1 = 3.
	Eigen::MatrixXd g(3, 3);
	g << 0, 1, 9, 1, 9, 9, 9, 9, 1;
	EXPECT_EQ(hungarian(g), (std::vector<int>{1, 0, 2}));
}

TEST(Hungarian, Rectangular)
{
	Eigen::MatrixXd c(2, 3);
	c << 5, 1, 2, 1, 5, 2;
	EXPECT_EQ(hungarian(c), (std::vector<int>{1, 0}));
	Eigen::MatrixXd t(3, 2);
	t << 5, 1, 1, 5, 3, 3;
	// Rows 0 and 1 take the 1s (2 total); any use of row 2 costs >= 4.
	EXPECT_EQ(hungarian(t), (std::vector<int>{1, 0, -1}));
	EXPECT_TRUE(hungarian(Eigen::MatrixXd(0, 3)).empty());
	Eigen::MatrixXd bad = Eigen::MatrixXd::Zero(2, 2);
	bad(0, 1) = std::numeric_limits<double>::infinity();
	EXPECT_THROW(hungarian(bad), std::invalid_argument);
}

TEST(Hungarian, MatchesBruteForceOnRandomMatrices)
{
	std::mt19937 rng(42);
	std::uniform_real_distribution<double> u(0, 10);
	for (int trial = 0; trial < 200; trial++)
	{
		const int n = 1 + trial % 5, m = n + (trial / 5) % 3;
		Eigen::MatrixXd c(n, m);
		for (int i = 0; i < n; i++)
			for (int j = 0; j < m; j++) c(i, j) = std::round(u(rng));
		const auto a = hungarian(c);
		std::vector<int> used;
		for (int x : a)
		{
			ASSERT_GE(x, 0);
			used.push_back(x);
		}
		std::sort(used.begin(), used.end());
		EXPECT_EQ(std::unique(used.begin(), used.end()), used.end());
		EXPECT_NEAR(totalCost(c, a), bruteForce(c), 1e-9) << c;
	}
}

TEST(MatchGated, MaximisesPairsBeforeDistance)
{
	// Greedy nearest-first would pair a0 with b1 (0.28 m) and leave b0
	// without a partner; the optimum pairs a0-b0 and a1-b1.
	const std::vector<Eigen::Vector2d> gt = {{0, 0}, {0.6, 0}};
	const std::vector<Eigen::Vector2d> est = {{0.32, 0}, {0.95, 0}};
	const auto m = matchGated(gt, est, 0.5);
	ASSERT_EQ(m.size(), 2u);
	EXPECT_EQ(m[0].a, 0u);
	EXPECT_EQ(m[0].b, 0u);
	EXPECT_NEAR(m[0].dist_m, 0.32, 1e-12);
	EXPECT_EQ(m[1].a, 1u);
	EXPECT_EQ(m[1].b, 1u);
	EXPECT_NEAR(m[1].dist_m, 0.35, 1e-12);
}

TEST(MatchGated, GateAndComponents)
{
	const std::vector<Eigen::Vector2d> gt = {{0, 0}, {10, 10}, {-50, 3}};
	const std::vector<Eigen::Vector2d> est = {
	    {10.5, 10}, {0.51, 0}, {-50, 3.5}};
	const auto m = matchGated(gt, est, 0.5);
	// {0,0}-{0.51,0} is outside the gate; {10,10}-{10.5,10} at exactly 0.5
	// is inside (gate inclusive).
	ASSERT_EQ(m.size(), 2u);
	EXPECT_EQ(m[0].a, 1u);
	EXPECT_EQ(m[0].b, 0u);
	EXPECT_NEAR(m[0].dist_m, 0.5, 1e-12);
	EXPECT_EQ(m[1].a, 2u);
	EXPECT_EQ(m[1].b, 2u);
	EXPECT_TRUE(matchGated({}, est, 0.5).empty());
	EXPECT_THROW(matchGated(gt, est, 0.0), std::invalid_argument);
}

TEST(MatchGated, LargeGridIsFastAndComplete)
{
	// 100 x 100 trees 2 m apart, each estimate shifted by 0.1 m: all match.
	std::vector<Eigen::Vector2d> gt, est;
	for (int i = 0; i < 100; i++)
		for (int j = 0; j < 100; j++)
		{
			gt.emplace_back(2.0 * i, 2.0 * j);
			est.emplace_back(2.0 * i + 0.1, 2.0 * j);
		}
	std::reverse(est.begin(), est.end());
	const auto m = matchGated(gt, est, 0.5);
	ASSERT_EQ(m.size(), gt.size());
	for (const auto& x : m)
	{
		EXPECT_EQ(x.b, gt.size() - 1 - x.a);
		EXPECT_NEAR(x.dist_m, 0.1, 1e-9);
	}
}
