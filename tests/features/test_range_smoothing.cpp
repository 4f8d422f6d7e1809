#include <forest_slam/core/config.h>
#include <forest_slam/features/range_smoothing.h>
#include <gtest/gtest.h>
#include <mrpt/config/CConfigFileMemory.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

using namespace forest_slam::features;

namespace
{
FeatureInputPoint at(int column, double range, double az_deg, int cluster,
                     bool ground = false, int ring = 0)
{
	const double az = az_deg * M_PI / 180;
	FeatureInputPoint p;
	p.xyz = Eigen::Vector3f(range * std::cos(az), range * std::sin(az),
	                        ground ? -1.5f : 0.f);
	p.column = static_cast<uint16_t>(column);
	p.ring = static_cast<uint16_t>(ring);
	p.cluster = ground ? -1 : cluster;
	p.ground = ground;
	return p;
}
}  // namespace

TEST(RangeSmoothing, OffLeavesThePointsAsMeasured)
{
	std::vector<FeatureInputPoint> pts;
	for (int c = 0; c < 50; c++)
		pts.push_back(at(c, 5 + 0.01 * (c % 3), 0.2 * c, 0));
	RangeSmoothingOptions off;
	off.half_window = 0;
	const auto out = smoothRanges(pts, off);
	ASSERT_EQ(out.size(), pts.size());
	for (size_t i = 0; i < pts.size(); i++) EXPECT_EQ(out[i], pts[i].xyz);
}

// Stems 3-8 m away with 2.5 cm of range noise, one ring at 0.2 deg steps
// (a VLP-16): the smoothed ranges keep the surface (no bias from the bulge)
// with about a third of the noise's variance; the ends of each stem's run
// are not moved.
TEST(RangeSmoothing, NoisyStemsKeepTheirSurfaceWithAThirdOfTheNoise)
{
	std::mt19937 rng(11);
	std::normal_distribution<double> noise(0, 0.025);
	RangeSmoothingOptions o;
	o.half_window = 3;
	double sum_err = 0, sum_err2 = 0, sum_noise2 = 0;
	size_t smoothed = 0, ends = 0;
	for (int trial = 0; trial < 100; trial++)
	{
		struct Stem
		{
			Eigen::Vector2d c;
			double r;
		};
		std::vector<Stem> stems;
		for (int s = 0; s < 12; s++)
		{
			const double az = (-55 + 10.0 * s) * M_PI / 180,
			             range = 3 + 5 * ((s * 7 + trial) % 12) / 11.0;
			stems.push_back({{range * std::cos(az), range * std::sin(az)},
			                 0.1 + 0.01 * ((s + trial) % 11)});
		}
		std::vector<FeatureInputPoint> pts;
		std::vector<double> truth;
		for (int c = 0; c < 600; c++)
		{
			const double az = -60 + 0.2 * c;
			const Eigen::Vector2d d(std::cos(az * M_PI / 180),
			                        std::sin(az * M_PI / 180));
			double r = 1e9;
			int hit = -1;
			for (size_t s = 0; s < stems.size(); s++)
			{
				const double b = d.dot(stems[s].c),
				             q = b * b - (stems[s].c.squaredNorm() -
				                          stems[s].r * stems[s].r);
				if (q >= 0 && b - std::sqrt(q) < r)
					r = b - std::sqrt(q), hit = static_cast<int>(s);
			}
			if (hit < 0) continue;  // no return
			pts.push_back(at(c, r + noise(rng), az, hit));
			truth.push_back(r);
		}
		const auto out = smoothRanges(pts, o);
		for (size_t i = 0; i < pts.size(); i++)
		{
			const double measured = pts[i].xyz.norm();
			// The direction is kept.
			EXPECT_LT(out[i].normalized().cross(pts[i].xyz.normalized()).norm(),
			          1e-5);
			if (out[i] == pts[i].xyz)
			{
				ends++;
				continue;
			}
			smoothed++;
			const double e = out[i].norm() - truth[i];
			sum_err += e;
			sum_err2 += e * e;
			sum_noise2 += (measured - truth[i]) * (measured - truth[i]);
		}
	}
	ASSERT_GT(smoothed, 10000u);
	ASSERT_GT(ends, 1000u);  // 2 x 3 per stem's run and single returns
	const double bias = sum_err / smoothed;
	const double ratio = sum_err2 / sum_noise2;
	std::printf("smoothed %zu, kept %zu: bias %.2f mm, variance ratio %.3f\n",
	            smoothed, ends, bias * 1e3, ratio);
	EXPECT_LT(std::abs(bias), 0.001);  // the bulge is fitted, not flattened
	EXPECT_LT(ratio, 0.40);            // 7-point quadratic: 1/3
	EXPECT_GT(ratio, 0.25);
}

// A run stops where the cluster changes, at a missing firing, at a range
// step and between ground and non-ground: no point is smoothed with
// another object's ranges.
TEST(RangeSmoothing, RunsStopAtClustersGapsAndSteps)
{
	RangeSmoothingOptions o;
	o.half_window = 2;
	std::vector<FeatureInputPoint> pts;
	// Cluster 0 at ~5 m (columns 0-9), cluster 1 at ~5.05 m (10-19), then a
	// missing column (20), cluster 1 again (21-30) with a 0.5 m step at 26;
	// a ground ring (ring 1) under it, columns 0-30.
	auto wiggle = [](int c) { return (c % 2 ? 0.01 : -0.01); };
	for (int c = 0; c <= 30; c++)
	{
		if (c == 20) continue;
		const int cluster = c < 10 ? 0 : 1;
		const double r =
		    (c < 10 ? 5.0 : 5.05) + (c >= 26 ? 0.5 : 0) + wiggle(c);
		pts.push_back(at(c, r, 0.2 * c, cluster));
		pts.push_back(at(c, 6 + wiggle(c), 0.2 * c, -1, true, 1));
	}
	const auto out = smoothRanges(pts, o);
	auto moved = [&](int column, int ring)
	{
		for (size_t i = 0; i < pts.size(); i++)
			if (pts[i].column == column && pts[i].ring == ring)
				return !(out[i] == pts[i].xyz);
		ADD_FAILURE() << "no point at column " << column;
		return false;
	};
	// Runs: [0, 9], [10, 19], [21, 25], [26, 30] on ring 0; [0, 19],
	// [21, 30] on the ground ring. All points but the runs' ends.
	for (int c = 0; c <= 30; c++)
	{
		if (c == 20) continue;
		const bool inner0 = (c >= 1 && c <= 8) || (c >= 11 && c <= 18) ||
		                    (c >= 22 && c <= 24) || (c >= 27 && c <= 29);
		const bool inner1 = (c >= 1 && c <= 18) || (c >= 22 && c <= 29);
		EXPECT_EQ(moved(c, 0), inner0) << "column " << c;
		EXPECT_EQ(moved(c, 1), inner1) << "ground column " << c;
	}
	// A smoothed point stays within its own object's ranges.
	for (size_t i = 0; i < pts.size(); i++)
		EXPECT_NEAR(out[i].norm(), pts[i].xyz.norm(), 0.02);
}

TEST(RangeSmoothing, BadIniValuesAreRejectedWithTheKey)
{
	for (const char* line :
	     {"range_smoothing_half_window = -1",
	      "range_smoothing_half_window = 21", "range_smoothing_max_step_m = 0",
	      "range_smoothing_half_window = three"})
	{
		mrpt::config::CConfigFileMemory c(std::string("[features]\n") + line +
		                                  "\n");
		FeatureOptions o;
		try
		{
			o.loadFromConfigFile(c, "features");
			ADD_FAILURE() << "accepted: " << line;
		}
		catch (const std::exception& e)
		{
			const std::string key =
			    std::string(line).substr(0, std::string(line).find(' '));
			EXPECT_NE(std::string(e.what()).find(key), std::string::npos)
			    << e.what();
		}
	}
	mrpt::config::CConfigFileMemory good(
	    "[features]\nrange_smoothing_half_window = 3\n"
	    "range_smoothing_max_step_m = 0.2\n");
	FeatureOptions o;
	o.loadFromConfigFile(good, "features");
	EXPECT_EQ(o.range_smoothing.half_window, 3);
	EXPECT_DOUBLE_EQ(o.range_smoothing.max_step_m, 0.2);
}
