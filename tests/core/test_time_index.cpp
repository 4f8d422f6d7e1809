// core::TimeIndex: constant-time lookups give the bisection's answers, on
// even and jittered scan times, at the bucket edges, on repeated times,
// before, after and between the times, and for NaN.
#include <forest_slam/core/time_index.h>
#include <gtest/gtest.h>

#include <limits>
#include <random>

using forest_slam::core::TimeIndex;

TEST(TimeIndex, SameAnswersAsBisection)
{
	std::mt19937 rng(5);
	std::uniform_real_distribution<double> jitter(0.0, 0.19), u(-1, 1001);
	std::vector<double> t;
	double now = 100;
	for (int i = 0; i < 9000; i++)
	{
		t.push_back(now);
		if (i % 700 == 0) t.push_back(now);                 // a repeated time
		now += i % 1000 == 999 ? 3.0 : 0.01 + jitter(rng);  // and gaps
	}
	const TimeIndex idx(t);
	std::vector<double> queries = {t.front() - 1, t.front(), t.back(),
	                               t.back() + 1};
	for (double q : t)
		for (double d : {-1e-9, 0.0, 1e-9}) queries.push_back(q + d);
	for (int i = 0; i < 100000; i++) queries.push_back(t.front() + u(rng));
	for (double q : queries) ASSERT_EQ(idx.at(q), idx.bisect(q)) << q;
	EXPECT_EQ(idx.at(t.front() - 5), 0u);
	EXPECT_EQ(idx.at(t.back() + 5), t.size() - 1);
	EXPECT_EQ(idx.at(std::numeric_limits<double>::quiet_NaN()), t.size() - 1);
	// A repeated time: the last of the equal ones.
	EXPECT_EQ(idx.at(t[1]), 1u);
	EXPECT_EQ(t[0], t[1]);
}

TEST(TimeIndex, DegenerateLists)
{
	EXPECT_EQ(TimeIndex({}).at(3.0), 0u);
	EXPECT_EQ(TimeIndex({2.0}).at(1.0), 0u);
	EXPECT_EQ(TimeIndex({2.0}).at(3.0), 0u);
	const TimeIndex same({1.0, 1.0, 1.0});
	EXPECT_EQ(same.at(0.5), 0u);
	EXPECT_EQ(same.at(1.0), 2u);
	EXPECT_EQ(same.at(2.0), 2u);
}
