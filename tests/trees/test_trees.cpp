// Tree layer: circle fit accuracy (issue 7 target), outlier removal, DTM and
// DBH on a slope, stem detection on a synthetic plot with shrubs and a wall,
// and the real TreeLS pine plot.
#include <forest_slam/io/las.h>
#include <forest_slam/trees/circle_fit.h>
#include <forest_slam/trees/outlier_filter.h>
#include <forest_slam/trees/stem_clustering.h>
#include <forest_slam/trees/stem_detector.h>
#include <forest_slam/trees/terrain_model.h>
#include <forest_slam/trees/tree_options.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>

using namespace forest_slam::trees;
using Pts = std::vector<Eigen::Vector3d>;

namespace
{
Points2D arc(std::mt19937& rng, const Eigen::Vector2d& c, double r,
             double from_deg, double span_deg, int n, double sigma)
{
	std::uniform_real_distribution<double> u(from_deg, from_deg + span_deg);
	std::normal_distribution<double> g(0, sigma);
	Points2D p;
	for (int i = 0; i < n; i++)
	{
		const double a = u(rng) * M_PI / 180;
		p.emplace_back(c.x() + (r + g(rng)) * std::cos(a),
		               c.y() + (r + g(rng)) * std::sin(a));
	}
	return p;
}

/** The ray from `s` at angle `a` [rad]: its first hit of the circle (c, r),
 * moved along the ray by `range_error()` (drawn only on a hit), into `p`
 * and its direction into `d`; false if it misses. */
template <class Noise>
bool castRay(const Eigen::Vector2d& s, double a, const Eigen::Vector2d& c,
             double r, Noise&& range_error, Points2D& p, Points2D& d)
{
	const Eigen::Vector2d dir(std::cos(a), std::sin(a));
	const double bb = (s - c).dot(dir), cc = (s - c).squaredNorm() - r * r;
	if (bb * bb - cc < 0) return false;
	p.push_back(s + (-bb - std::sqrt(bb * bb - cc) + range_error()) * dir);
	d.push_back(dir);
	return true;
}

CircleFitOptions opts()
{
	CircleFitOptions o;
	o.min_radius_m = 0.02;
	o.max_radius_m = 0.8;
	return o;
}
}  // namespace

// Issue 7: a 30 cm stem seen over 90° with 200 points and σ = 1 cm, mean DBH
// error over 1000 trials <= 2 mm.
TEST(CircleFit, PartialArc90DegreesUnbiased)
{
	std::mt19937 rng(42);
	double sum = 0, sum_abs = 0, sum_sq = 0, kasa_sum = 0;
	const int trials = 1000;
	for (int t = 0; t < trials; t++)
	{
		const auto p =
		    arc(rng, {1.0, -2.0}, 0.15, 360.0 * t / trials, 90, 200, 0.01);
		const auto f = fitCircleRobust(p, opts());
		ASSERT_TRUE(f.ok);
		const double e = 2 * f.circle.radius_m - 0.30;
		sum += e, sum_abs += std::abs(e), sum_sq += e * e;
		Circle k;
		ASSERT_TRUE(fitCircleKasa(p, k));
		kasa_sum += 2 * k.radius_m - 0.30;
	}
	std::printf(
	    "90 deg arc, 1000 trials: mean DBH error %.2f mm, MAE %.2f mm, RMSE "
	    "%.2f mm "
	    "(Kasa alone: mean %.2f mm)\n",
	    1e3 * sum / trials, 1e3 * sum_abs / trials,
	    1e3 * std::sqrt(sum_sq / trials), 1e3 * kasa_sum / trials);
	EXPECT_LE(std::abs(sum / trials), 0.002);
	// The algebraic start alone is biased on partial arcs: that is why it is
	// only a start.
	EXPECT_LT(kasa_sum / trials, -0.005);
}

// Lidar range noise is along the rays. Seen from one side, the noise moves
// the silhouette points along the tangent (always outwards) and a
// free-centre orthogonal fit shrinks the circle; the along-ray residuals are
// exact for the true circle, so that fit stays unbiased.
// A small circle through part of a ring (a local optimum of the robust fit:
// the robot run's GT 1465, 50 deg and r 10.3 cm against slices at 19.8 cm
// over 180-215 deg) is replaced by the fit started from the slices' circle;
// a fit that agrees with the slices, or sees as much of the stem, stays.
TEST(CircleFit, SmallCircleThroughPartOfTheRingIsCheckedAgainstTheSlices)
{
	std::mt19937 rng(7);
	const Eigen::Vector2d c(0.02, -0.01);  // the band's centre, off the axis
	const double r = 0.197;
	const Points2D ring = arc(rng, c, r, 100, 200, 400, 0.008);
	auto o = opts();
	o.min_radius_m = 0.095, o.max_radius_m = 0.3;  // 0.5-1.5 x the slices'
	// The wrong circle, as in that run: radius 10.3 cm, centred 17 cm from
	// the stem's centre towards the middle of the seen arc.
	const Eigen::Vector2d mid(std::cos(200 * M_PI / 180),
	                          std::sin(200 * M_PI / 180));
	const Circle small{c + mid * 0.172, 0.103};
	const CircleFitResult wrong = evaluateCircle(ring, small, o);
	ASSERT_LT(arcCoverageDeg(ring, small, 2 * o.ransac_inlier_m, o.arc_bin_deg),
	          100);
	const Circle slices{Eigen::Vector2d::Zero(), 0.198};
	const auto fixed = checkAgainstReference(ring, wrong, slices, 200, o, 15);
	EXPECT_NEAR(fixed.circle.radius_m, r, 0.005);
	EXPECT_LT((fixed.circle.centre - c).norm(), 0.01);
	EXPECT_GT(fixed.arc_coverage_deg, 180);
	// The right circle stays, whatever the slices say.
	const auto good = fitCircleRobust(ring, o);
	ASSERT_NEAR(good.circle.radius_m, r, 0.005);
	const Circle other{Eigen::Vector2d::Zero(), 0.12};
	for (const auto& ref : {slices, other})
	{
		const auto kept = checkAgainstReference(ring, good, ref, 200, o, 15);
		EXPECT_EQ(kept.circle.radius_m, good.circle.radius_m);
		EXPECT_EQ(kept.circle.centre, good.circle.centre);
	}
	// Slices that saw no more of the stem than the fit: no second opinion.
	const auto same = checkAgainstReference(ring, wrong, slices, 100, o, 15);
	EXPECT_EQ(same.circle.radius_m, wrong.circle.radius_m);
}

TEST(CircleFit, AlongRayNoiseOneSidedView)
{
	std::mt19937 rng(3);
	std::normal_distribution<double> g(0, 0.025);
	std::uniform_real_distribution<double> u(0, 2 * M_PI);
	const double r = 0.10, range = 8.0;
	double sum_ray = 0, sum_orth = 0;
	const int trials = 200;
	for (int t = 0; t < trials; t++)
	{
		const double view = u(rng);
		const Eigen::Vector2d c(1.0, 2.0);
		const Eigen::Vector2d s =
		    c + range * Eigen::Vector2d(std::cos(view), std::sin(view));
		Points2D p, d;
		const double half = std::asin(r / range);
		// A lidar's fixed angular step across the stem (0.05°).
		for (double b = -half; b <= half; b += 0.05 * M_PI / 180)
			castRay(
			    s, view + M_PI + b, c, r, [&] { return g(rng); }, p, d);
		const auto f = fitCircleRobust(p, opts());
		ASSERT_TRUE(f.ok);
		Circle ray = f.circle;
		ASSERT_TRUE(refineCircleAlongRays(p, d, ray));
		sum_orth += f.circle.radius_m - r;
		sum_ray += ray.radius_m - r;
	}
	std::printf(
	    "one view, r 10 cm, along-ray sigma 2.5 cm: mean radius error "
	    "orthogonal %.1f mm, along-ray %.1f mm\n",
	    1e3 * sum_orth / trials, 1e3 * sum_ray / trials);
	EXPECT_LT(sum_orth / trials, -0.005);
	EXPECT_LE(std::abs(sum_ray / trials), 0.002);
}

// A small stem far away (r 5 cm at 12 m, range noise 2.5 cm: half the
// radius): the lateral spread of the rays that hit it gives the radius
// (within 2.5 mm: the reach of 4 cm cuts the front's largest range errors),
// and a centre off along the rays (the range) hardly changes it; points
// without a direction or beyond the reach are left out.
TEST(CircleFit, SilhouetteRadiusOfASmallFarStem)
{
	std::mt19937 rng(5);
	std::normal_distribution<double> g(0, 0.025);
	std::uniform_real_distribution<double> u(0, 1);
	const double r = 0.05, range = 12.0, step = 0.2 * M_PI / 180;
	double sum = 0, sum_sq = 0;
	const int trials = 200;
	for (int t = 0; t < trials; t++)
	{
		const double view = 2 * M_PI * u(rng);
		const Eigen::Vector2d c(1.0, 2.0);
		const Eigen::Vector2d s =
		    c + range * Eigen::Vector2d(std::cos(view), std::sin(view));
		Points2D p, d;
		const double half = std::asin(r / range);
		// 100 scans, each firing at its own phase of the 0.2 deg step.
		for (int scan = 0; scan < 100; scan++)
			for (double b = -half + step * u(rng); b <= half; b += step)
				castRay(
				    s, view + M_PI + b, c, r, [&] { return g(rng); }, p, d);
		// Clutter: far off the stem, and a point with no known ray.
		p.emplace_back(c + Eigen::Vector2d(0.5, 0.0));
		d.emplace_back(1.0, 0.0);
		p.emplace_back(c + Eigen::Vector2d(0.0, 0.2 * r));
		d.emplace_back(0.0, 0.0);
		// The centre off by 1 cm along the view: same lateral offsets.
		const Eigen::Vector2d along = (c - s).normalized();
		const double rs =
		    silhouetteRadius(p, d, Circle{c + 0.01 * along, r}, 0.04, 15);
		ASSERT_TRUE(std::isfinite(rs));
		sum += rs - r;
		sum_sq += (rs - r) * (rs - r);
	}
	const double mean = sum / trials,
	             sd = std::sqrt(sum_sq / trials - mean * mean);
	std::printf(
	    "silhouette radius, r 5 cm at 12 m, range sigma 2.5 cm: mean "
	    "error %.2f mm, sd %.2f mm\n",
	    1e3 * mean, 1e3 * sd);
	EXPECT_GE(mean, 0.0);
	EXPECT_LE(mean, 0.0025);
	EXPECT_LE(sd, 0.003);
	// Too few points with a direction: no estimate.
	Points2D p{{0.0, 0.05}, {0.05, 0.0}}, d{{1.0, 0.0}, {0.0, 0.0}};
	EXPECT_TRUE(
	    std::isnan(silhouetteRadius(p, d, Circle{{0, 0}, 0.05}, 0.06, 2)));
	EXPECT_NEAR(silhouetteRadius(p, d, Circle{{0, 0}, 0.05}, 0.06, 1),
	            std::sqrt(3.0) * 0.05, 1e-12);
}

namespace
{
/** The rays of one straight pass by a stem (centre c, radius r) at 10 Hz
 * and 1 m/s, 0.2 deg azimuth steps, x from x0 to -x0 (`back`: from -x0 to
 * x0), range noise from `noise`. The map's odometry is off by
 * `scale_error` along the walk about its middle (x = 0): every point moves
 * by scale_error * x along x. Times start at t0. */
void passBy(const Eigen::Vector2d& c, double r, double scale_error, double x0,
            bool back, double t0, std::mt19937& rng,
            std::normal_distribution<double>& noise, Points2D& p, Points2D& d,
            std::vector<double>& time)
{
	for (int k = 0; k <= 300; k++)
	{
		const double along = x0 + 0.1 * k;
		const double x = back ? -along : along;
		const Eigen::Vector2d s(x, 0);
		const Eigen::Vector2d shift(scale_error * x, 0);
		const double dist = (c - s).norm();
		const double view = std::atan2(c.y() - s.y(), c.x() - s.x());
		const double half = std::asin(r / dist);
		for (double b = -half; b <= half; b += 0.2 * M_PI / 180)
		{
			const double a = view + b;
			const Eigen::Vector2d dir(std::cos(a), std::sin(a));
			const double bb = (s - c).dot(dir),
			             cc = (s - c).squaredNorm() - r * r;
			if (bb * bb - cc < 0) continue;
			p.push_back(s + shift +
			            (-bb - std::sqrt(bb * bb - cc) + noise(rng)) * dir);
			d.push_back(dir);
			time.push_back(t0 + 0.1 * k);
		}
	}
}
}  // namespace

// A stem passed by on a straight walk, in a map whose odometry under-
// estimates the distance walked by 0.3 % (the drift of forest-sim's
// handheld odometry is 0.13 %): the stem's points move along the walk while
// the view sweeps round it, so its first and last sides come out squashed
// together and one circle through them is too small. Letting the centre
// drift linearly in time recovers the radius.
TEST(CircleFit, AlongRayDriftDuringAPass)
{
	std::mt19937 rng(11);
	std::normal_distribution<double> g(0, 0.025);
	const Eigen::Vector2d c(0.0, 8.0);
	const double r = 0.15, scale_error = -0.003;
	double sum_still = 0, sum_drift = 0, max_drift = 0;
	const int trials = 20;
	for (int t = 0; t < trials; t++)
	{
		Points2D p, d;
		std::vector<double> time;
		passBy(c, r, scale_error, -15 + 0.01 * t, false, 0, rng, g, p, d, time);
		const auto f = fitCircleRobust(p, opts());
		ASSERT_TRUE(f.ok);
		Circle still = f.circle, moving = f.circle;
		ASSERT_TRUE(refineCircleAlongRays(p, d, still));
		RayFitOptions ro;
		ro.times = &time;
		ro.drift_sigma_m_per_s = 0.005;
		Eigen::Vector2d v;
		ASSERT_TRUE(refineCircleAlongRays(p, d, moving, ro, &v));
		sum_still += still.radius_m - r;
		sum_drift += moving.radius_m - r;
		max_drift = std::max(max_drift, std::abs(moving.radius_m - r));
		EXPECT_NEAR(v.x(), scale_error, 0.0015);
		EXPECT_NEAR(v.y(), 0.0, 0.0015);
	}
	std::printf(
	    "pass by a 30 cm stem, 0.3 %% odometry scale error: mean radius "
	    "error %.1f mm still, %.1f mm with drift (max %.1f mm)\n",
	    1e3 * sum_still / trials, 1e3 * sum_drift / trials, 1e3 * max_drift);
	EXPECT_LT(sum_still / trials, -0.01);
	EXPECT_LE(std::abs(sum_drift / trials), 0.002);
	EXPECT_LE(max_drift, 0.005);
}

// The same stem passed by twice, there and back five minutes apart (a loop
// closure aligned the passes): each pass is squashed along its own walk,
// so in time the two drift in opposite directions. One drift over both
// passes is held near zero by the minutes between them and leaves the
// stem too small; a drift per pass (RayFitOptions::pass_gap_s) recovers it.
TEST(CircleFit, AlongRayDriftPerPass)
{
	std::mt19937 rng(12);
	std::normal_distribution<double> g(0, 0.025);
	const Eigen::Vector2d c(0.0, 8.0);
	const double r = 0.15, scale_error = -0.003;
	double sum_one = 0, sum_per_pass = 0;
	const int trials = 10;
	for (int t = 0; t < trials; t++)
	{
		Points2D p, d;
		std::vector<double> time;
		// There, and 300 s later back: the same shift field in x (squashed
		// along each walk about its middle), opposite drifts in time.
		passBy(c, r, scale_error, -15 + 0.01 * t, false, 0, rng, g, p, d, time);
		passBy(c, r, scale_error, -15 + 0.01 * t, true, 300, rng, g, p, d,
		       time);
		const auto f = fitCircleRobust(p, opts());
		ASSERT_TRUE(f.ok);
		Circle one = f.circle, per_pass = f.circle;
		RayFitOptions ro;
		ro.times = &time;
		ro.drift_sigma_m_per_s = 0.005;
		ro.pass_gap_s = 1e9;  // one drift for both passes
		ASSERT_TRUE(refineCircleAlongRays(p, d, one, ro));
		ro.pass_gap_s = 30;
		Eigen::Vector2d v;
		ASSERT_TRUE(refineCircleAlongRays(p, d, per_pass, ro, &v));
		sum_one += one.radius_m - r;
		sum_per_pass += per_pass.radius_m - r;
		EXPECT_NEAR(std::abs(v.x()), std::abs(scale_error), 0.0015);
	}
	std::printf(
	    "two passes by a 30 cm stem, 0.3 %% scale error: mean radius error "
	    "%.1f mm with one drift, %.1f mm with a drift per pass\n",
	    1e3 * sum_one / trials, 1e3 * sum_per_pass / trials);
	EXPECT_LT(sum_one / trials, -0.005);
	EXPECT_LE(std::abs(sum_per_pass / trials), 0.002);
}

// Multi-view fit (SLAM run): three time segments see a 30 cm stem from
// three sides (σ = 1 cm along the rays), each shifted by a pose error of
// 4 cm towards its sensor. One circle through the union is too
// large (doubled rings); one shift per segment recovers the DBH and the
// consensus centre, and the shifts themselves (relative to their mean).
TEST(CircleFit, SegmentShiftsRecoverDoubledRings)
{
	std::mt19937 rng(7);
	std::normal_distribution<double> g(0, 0.01);
	const Eigen::Vector2d c(3.0, -1.0);
	const double r = 0.15, range = 5.0;
	double sum_union = 0, sum_seg = 0, max_seg = 0, max_shift_err = 0;
	const int trials = 50;
	for (int t = 0; t < trials; t++)
	{
		Points2D p, d, shift(3);
		std::vector<uint32_t> seg;
		for (int s = 0; s < 3; s++)
		{
			const double view = 2 * M_PI * s / 3 + 0.3 * t;
			// Towards the sensor: the worst case, the union looks like one
			// circle 4 cm too large.
			shift[s] = 0.04 * Eigen::Vector2d(std::cos(view), std::sin(view));
			const Eigen::Vector2d o =
			    c + range * Eigen::Vector2d(std::cos(view), std::sin(view));
			const double half = std::asin(r / range);
			for (double b = -half; b <= half; b += 0.02 * M_PI / 180)
			{
				const double a = view + M_PI + b;
				const Eigen::Vector2d dir(std::cos(a), std::sin(a));
				const double bb = (o - c).dot(dir),
				             cc = (o - c).squaredNorm() - r * r;
				if (bb * bb - cc < 0) continue;
				p.push_back(o + (-bb - std::sqrt(bb * bb - cc) + g(rng)) * dir +
				            shift[s]);
				d.push_back(dir);
				seg.push_back(uint32_t(10 + s));
			}
		}
		const auto f = fitCircleRobust(p, opts());
		ASSERT_TRUE(f.ok);
		sum_union += f.circle.radius_m - r;
		Circle cs = f.circle;
		Points2D sh;
		ASSERT_TRUE(refineCircleSegments(p, d, seg, 0.05, cs, &sh));
		ASSERT_EQ(sh.size(), p.size());
		sum_seg += cs.radius_m - r;
		max_seg = std::max(max_seg, std::abs(cs.radius_m - r));
		// Shifts are found up to their common part (the consensus centre
		// absorbs it): compare centre + shift with the truth.
		for (size_t i = 0; i < p.size(); i++)
			max_shift_err =
			    std::max(max_shift_err,
			             (cs.centre + sh[i] - (c + shift[seg[i] - 10])).norm());
	}
	std::printf(
	    "3 views, rings offset 4 cm: mean radius error union %.1f mm, per-"
	    "segment shifts %.2f mm (max %.1f mm), segment circle centre error "
	    "max %.1f mm\n",
	    1e3 * sum_union / trials, 1e3 * sum_seg / trials, 1e3 * max_seg,
	    1e3 * max_shift_err);
	EXPECT_GT(sum_union / trials, 0.02);  // the doubled rings inflate it
	EXPECT_LE(std::abs(sum_seg / trials), 0.001);
	EXPECT_LE(max_seg, 0.004);
	EXPECT_LE(max_shift_err, 0.006);
}

// fitDbhSegments: the same three offset views as band points of one stem,
// started from the inflated union circle: the DBH within 5 mm; with a
// single segment (no shifts possible) it stays a plain fit of the union.
TEST(CircleFit, DbhSegmentsFromInflatedStart)
{
	std::mt19937 rng(11);
	std::normal_distribution<double> g(0, 0.01);
	const double r = 0.12, range = 4.0;
	Points2D p, d;
	std::vector<uint32_t> seg;
	for (int s = 0; s < 3; s++)
	{
		const double view = 2 * M_PI * s / 3;
		const Eigen::Vector2d o =
		    range * Eigen::Vector2d(std::cos(view), std::sin(view));
		const double half = std::asin(r / range);
		for (double b = -half; b <= half; b += 0.02 * M_PI / 180)
		{
			const double a = view + M_PI + b;
			const Eigen::Vector2d dir(std::cos(a), std::sin(a));
			const double bb = o.dot(dir), cc = o.squaredNorm() - r * r;
			if (bb * bb - cc < 0) continue;
			p.push_back(o + (-bb - std::sqrt(bb * bb - cc) + g(rng)) * dir +
			            0.03 * o / range);
			d.push_back(dir);
			seg.push_back(uint32_t(s + 1));
		}
	}
	TreeOptions o;
	const auto u = fitCircleRobust(p, opts());
	ASSERT_TRUE(u.ok);
	const double gate = std::max(4 * u.scale_m, 2 * o.ransac_inlier_m);
	const auto f = fitDbhSegments(p, d, seg, u.circle, gate, o, 0.5 * r, 2 * r);
	ASSERT_TRUE(f.ok);
	std::printf(
	    "fitDbhSegments: union r %.1f mm, segments r %.1f mm (true %.1f)\n",
	    1e3 * u.circle.radius_m, 1e3 * f.circle.radius_m, 1e3 * r);
	EXPECT_GT(u.circle.radius_m - r, 0.015);
	EXPECT_NEAR(f.circle.radius_m, r, 0.0025);
	EXPECT_LT(f.rmse_m, 0.02);
	const std::vector<uint32_t> one(p.size(), 5);
	const auto f1 =
	    fitDbhSegments(p, d, one, u.circle, gate, o, 0.5 * r, 2 * r);
	ASSERT_TRUE(f1.ok);
	EXPECT_GT(f1.circle.radius_m - r, 0.015);
	// Mismatched sizes are refused.
	EXPECT_FALSE(fitDbhSegments(p, d, std::vector<uint32_t>(3, 1), u.circle,
	                            gate, o, 0.5 * r, 2 * r)
	                 .ok);
}

TEST(CircleFit, FullArcAndBranchStub)
{
	std::mt19937 rng(7);
	auto p = arc(rng, {0, 0}, 0.20, 0, 360, 300, 0.005);
	auto f = fitCircleRobust(p, opts());
	ASSERT_TRUE(f.ok);
	EXPECT_NEAR(f.circle.radius_m, 0.20, 0.002);
	EXPECT_NEAR(f.circle.centre.norm(), 0, 0.002);
	EXPECT_GT(f.arc_coverage_deg, 340);
	// A branch stub: 80 points on a short segment leaving the stem.
	std::uniform_real_distribution<double> u(0.21, 0.45);
	for (int i = 0; i < 80; i++) p.emplace_back(u(rng), 0.01 * (i % 3));
	f = fitCircleRobust(p, opts());
	ASSERT_TRUE(f.ok);
	EXPECT_NEAR(f.circle.radius_m, 0.20, 0.003);
	EXPECT_NEAR(f.circle.centre.norm(), 0, 0.003);
	Circle k;
	ASSERT_TRUE(fitCircleKasa(p, k));
	EXPECT_GT(std::abs(k.radius_m - 0.20),
	          0.01);  // the stub does pull a plain fit
}

// RANSAC stops once an all-inlier 3-point sample is likely (99.9 %): about
// 10 samples at 80 % inliers, the cap when few points are inliers, and the
// fit still finds a stem with a third of its cluster clutter (about 20
// samples drawn). (With more clutter than stem points the MAD scale of the
// refinement breaks down, 300 samples or not: the ring search handles
// such clusters.)
TEST(CircleFit, RansacStopsWhenACleanSampleIsLikely)
{
	EXPECT_EQ(ransacIterationsNeeded(0.8, 1, 300), 10);  // ln 0.001/ln 0.488
	EXPECT_EQ(ransacIterationsNeeded(0.5, 1, 300), 52);
	EXPECT_EQ(ransacIterationsNeeded(0.8, 20, 300), 20);
	EXPECT_EQ(ransacIterationsNeeded(0.1, 20, 300), 300);
	EXPECT_EQ(ransacIterationsNeeded(0.0, 20, 300), 300);
	EXPECT_EQ(ransacIterationsNeeded(1.0, 20, 300), 20);

	std::mt19937 rng(11);
	auto p = arc(rng, {0.3, -0.2}, 0.15, 0, 360, 200, 0.004);
	std::uniform_real_distribution<double> u(-0.5, 0.5);
	for (int i = 0; i < 100; i++) p.emplace_back(0.3 + u(rng), -0.2 + u(rng));
	const auto f = fitCircleRobust(p, opts());
	ASSERT_TRUE(f.ok);
	EXPECT_NEAR(f.circle.radius_m, 0.15, 0.003);
	EXPECT_NEAR((f.circle.centre - Eigen::Vector2d(0.3, -0.2)).norm(), 0,
	            0.003);
}

// A stem inside a shrub: foliage points all around it, outside its ring
// (the stem is solid). The robust fit takes the foliage into a larger
// ring; the solid-ring fit finds the stem. On a clean ring it changes
// nothing that matters.
TEST(CircleFit, SolidRingInsideFoliage)
{
	std::mt19937 rng(11);
	const double r = 0.15;
	auto p = arc(rng, {0.3, -0.2}, r, 0, 360, 400, 0.015);
	const auto clean = fitCircleRobust(p, opts());
	ASSERT_TRUE(clean.ok);
	const Circle clean_solid = fitSolidRing(p, clean.circle, 0.03, 500, 1);
	EXPECT_NEAR(clean_solid.radius_m, clean.circle.radius_m, 0.002);
	// Foliage: 1000 points uniform over the annulus [r, r + 0.3 m].
	std::uniform_real_distribution<double> ang(0, 2 * M_PI), u(0, 1);
	for (int i = 0; i < 1000; i++)
	{
		const double a = ang(rng),
		             d = std::sqrt(r * r +
		                           u(rng) * ((r + 0.3) * (r + 0.3) - r * r));
		p.emplace_back(0.3 + d * std::cos(a), -0.2 + d * std::sin(a));
	}
	const auto robust = fitCircleRobust(p, opts());
	ASSERT_TRUE(robust.ok);
	const Circle solid = fitSolidRing(p, robust.circle, 0.03, 500, 1);
	std::printf(
	    "stem r %.0f mm in foliage: robust fit %.1f mm, solid ring "
	    "%.1f mm (centre off by %.1f mm)\n",
	    1e3 * r, 1e3 * robust.circle.radius_m, 1e3 * solid.radius_m,
	    1e3 * (solid.centre - Eigen::Vector2d(0.3, -0.2)).norm());
	EXPECT_GT(robust.circle.radius_m, r + 0.01);  // the foliage does pull
	EXPECT_NEAR(solid.radius_m, r, 0.005);
	EXPECT_LT((solid.centre - Eigen::Vector2d(0.3, -0.2)).norm(), 0.005);
	// Deterministic for a seed.
	const Circle again = fitSolidRing(p, robust.circle, 0.03, 500, 1);
	EXPECT_EQ(again.radius_m, solid.radius_m);
}

TEST(OutlierFilter, RemovesScatteredPointsKeepsTheStem)
{
	std::mt19937 rng(3);
	auto p = arc(rng, {0, 0}, 0.15, 0, 200, 300, 0.003);
	const size_t n_stem = p.size();
	std::uniform_real_distribution<double> u(-0.6, 0.6);
	for (int i = 0; i < 15; i++)
		p.emplace_back(u(rng) > 0 ? 0.4 + 0.2 * i / 15.0 : -0.5, u(rng));
	const auto keep = statisticalOutlierFilter(p, 10, 0.4);
	size_t kept_stem = 0, kept_out = 0;
	for (size_t i : keep) (i < n_stem ? kept_stem : kept_out)++;
	EXPECT_EQ(kept_out, 0u);
	EXPECT_GT(kept_stem, n_stem / 2);
	// Fewer than k+1 points: nothing to judge, keep all.
	EXPECT_EQ(
	    statisticalOutlierFilter(Points2D(5, Eigen::Vector2d::Zero()), 10, 0.4)
	        .size(),
	    5u);
}

// The neighbourhood criterion joins k-means leaves whose points come closer
// than link_distance_m: two arcs 6 cm apart are one object, 10 cm apart two.
TEST(SliceClustering, LeavesJoinedWithinLinkDistance)
{
	for (const double gap : {0.06, 0.10})
	{
		std::mt19937 rng(9);
		auto p = arc(rng, {0, 0}, 0.15, 0, 360, 400, 0.002);
		// A second stem whose bark is `gap` from the first one's.
		const auto q = arc(rng, {0.30 + gap, 0}, 0.15, 0, 360, 400, 0.002);
		p.insert(p.end(), q.begin(), q.end());
		const auto leaf = sliceKMeansLeaves(p, 4, 75);
		const int n_leaves = *std::max_element(leaf.begin(), leaf.end()) + 1;
		EXPECT_GE(n_leaves, 8);  // k-means alone splits the stems
		const auto c = mergeLeavesByNeighbourhood(p, leaf, 0.08);
		size_t big = 0;
		for (const auto& x : c) big += x.size() >= 100;
		EXPECT_EQ(big, gap < 0.08 ? 1u : 2u) << "gap " << gap;
	}
}

// thinToCells merges input that comes as a few sorted runs (the tree
// layer's slices: one run per column read) instead of sorting it: the cells,
// their centroids (summed in input order) and each point's cell must be the
// same as by definition, with few runs and with many.
TEST(SliceClustering, ThinToCellsSameOnSortedRunsAndAnyOrder)
{
	std::mt19937 rng(3);
	std::uniform_real_distribution<double> u(-0.5, 0.5);
	const double cell = 0.02;
	auto keyOf = [&](const Eigen::Vector2d& q)
	{
		return std::make_pair(int64_t(std::floor(q.x() / cell)),
		                      int64_t(std::floor(q.y() / cell)));
	};
	Points2D runs;  // three runs, each sorted by cell
	for (int r = 0; r < 3; r++)
	{
		Points2D run(3000);
		for (auto& q : run) q = {u(rng), u(rng)};
		std::stable_sort(run.begin(), run.end(),
		                 [&](const auto& a, const auto& b)
		                 { return keyOf(a) < keyOf(b); });
		runs.insert(runs.end(), run.begin(), run.end());
	}
	Points2D shuffled = runs;
	std::shuffle(shuffled.begin(), shuffled.end(), rng);
	for (const Points2D* in : {&runs, &shuffled})
	{
		// By definition: cells in key order, points summed in input order.
		std::map<std::pair<int64_t, int64_t>, std::vector<size_t>> cells;
		for (size_t i = 0; i < in->size(); i++)
			cells[keyOf((*in)[i])].push_back(i);
		std::vector<uint32_t> cell_of;
		const Points2D out = thinToCells(*in, cell, &cell_of);
		ASSERT_EQ(out.size(), cells.size());
		size_t k = 0;
		for (const auto& [key, idx] : cells)
		{
			Eigen::Vector2d sum = Eigen::Vector2d::Zero();
			for (size_t i : idx)
			{
				sum += (*in)[i];
				ASSERT_EQ(cell_of[i], k);
			}
			const Eigen::Vector2d c = sum / double(idx.size());
			ASSERT_EQ(out[k].x(), c.x()) << "cell " << k;
			ASSERT_EQ(out[k].y(), c.y()) << "cell " << k;
			k++;
		}
	}
}

namespace
{
double groundZ(double x, double y)
{
	return 0.25 * x - 0.1 * y + 0.05 * std::sin(x);
}

void addGround(Pts& out, std::mt19937& rng, double size, int n)
{
	std::uniform_real_distribution<double> u(0, size);
	std::normal_distribution<double> g(0, 0.01);
	for (int i = 0; i < n; i++)
	{
		const double x = u(rng), y = u(rng);
		out.emplace_back(x, y, groundZ(x, y) + g(rng));
	}
}

/** A stem whose radius tapers with height above its base. */
void addStem(Pts& out, std::mt19937& rng, double x, double y, double r0,
             double taper, double height, int n)
{
	std::uniform_real_distribution<double> a(0, 2 * M_PI), h(0, height);
	std::normal_distribution<double> g(0, 0.004);
	const double z0 = groundZ(x, y);
	for (int i = 0; i < n; i++)
	{
		const double hh = h(rng), aa = a(rng), r = r0 - taper * hh + g(rng);
		out.emplace_back(x + r * std::cos(aa), y + r * std::sin(aa), z0 + hh);
	}
}

struct Truth
{
	double x, y, dbh;
};

void match(const std::vector<DetectedTree>& found,
           const std::vector<Truth>& truth, double& recall, double& precision,
           double& dbh_rmse)
{
	size_t tp = 0;
	double ss = 0;
	for (const auto& t : truth)
		for (const auto& f : found)
			if (std::hypot(f.record.x - t.x, f.record.y - t.y) < 0.3)
			{
				tp++;
				ss += std::pow(f.record.dbh_m - t.dbh, 2);
				break;
			}
	recall = double(tp) / truth.size();
	precision = found.empty() ? 0 : double(tp) / found.size();
	dbh_rmse = tp ? std::sqrt(ss / tp) : 0;
}
}  // namespace

// DBH must be taken 1.3 m above the *local* ground: on a 25 % slope with
// tapering stems, measuring from the plot's lowest point would change the
// diameter by centimetres.
TEST(Trees, SlopeDtmAndDbhAtLocalBreastHeight)
{
	std::mt19937 rng(11);
	Pts pts;
	addGround(pts, rng, 12, 40000);
	const std::vector<Truth> truth_pos = {{3, 3, 0}, {8, 4, 0}, {5, 9, 0}};
	std::vector<Truth> truth;
	for (const auto& t : truth_pos)
	{
		addStem(pts, rng, t.x, t.y, 0.20, 0.03, 8, 12000);
		truth.push_back({t.x, t.y, 2 * (0.20 - 0.03 * 1.3)});
	}
	TreeOptions o;
	const auto dtm = buildDtm(pts, o);
	double worst = 0;
	// Interior only: within dtm_window_cells of the border the median window
	// is one-sided and a steep slope can reject the border cells
	// (doc/trees.md).
	for (double x = 2.5; x <= 9.5; x += 0.7)
		for (double y = 2.5; y <= 9.5; y += 0.7)
			worst =
			    std::max(worst, std::abs(dtm.heightAt(x, y) - groundZ(x, y)));
	EXPECT_LT(worst, 0.06) << "DTM error on the slope";
	for (const auto& t : truth)
		EXPECT_NEAR(dtm.heightAt(t.x, t.y), groundZ(t.x, t.y), 0.05);

	const auto found = detectTrees(pts, dtm, o);
	ASSERT_EQ(found.size(), truth.size());
	for (const auto& t : truth)
	{
		const DetectedTree* f = nullptr;
		for (const auto& c : found)
			if (std::hypot(c.record.x - t.x, c.record.y - t.y) < 0.05) f = &c;
		ASSERT_NE(f, nullptr);
		EXPECT_NEAR(f->record.dbh_m, t.dbh, 0.006);
		EXPECT_NEAR(f->record.z_ground, groundZ(t.x, t.y), 0.05);
		EXPECT_GT(f->record.height_m, 7.0);
		EXPECT_LT(f->record.height_m, 8.5);
		EXPECT_EQ(f->record.quality, 0);
	}
}

// Where the ground is hidden (seen from afar behind stems and shrubs) the
// lowest points of most cells are clutter metres up, the majority of the
// median's window: without the slope bound the DTM there is the clutter's
// height (the 58-minute run: 3.4 m under two stems, doc/trees.md "Trees
// beyond 15 m of the path"). Flat ground at z = 0 around a 6 x 6 m patch
// that sees only clutter at 3.5-4.5 m, except two cells of ground inside.
TEST(Trees, DtmWhereTheGroundIsHiddenStaysOnTheGround)
{
	std::mt19937 rng(17);
	std::uniform_real_distribution<double> u(0, 1);
	Pts pts;
	auto inPatch = [](double x, double y)
	{ return x >= 8 && x < 14 && y >= 8 && y < 14; };
	auto groundSeen = [](double x, double y)
	{
		return (x >= 9.5 && x < 10.5 && y >= 9.5 && y < 10.5) ||
		       (x >= 12 && x < 13 && y >= 12 && y < 13);
	};
	for (int i = 0; i < 60000; i++)
	{
		const double x = 22 * u(rng), y = 22 * u(rng);
		if (!inPatch(x, y) || groundSeen(x, y))
			pts.emplace_back(x, y, 0.02 * (u(rng) - 0.5));
		else
			pts.emplace_back(x, y, 3.5 + u(rng));
	}
	TreeOptions o;
	o.dtm_max_slope_deg = 45;
	const auto dtm = buildDtm(pts, o);
	double worst = 0;
	for (double x = 8.25; x < 14; x += 0.5)
		for (double y = 8.25; y < 14; y += 0.5)
			worst = std::max(worst, std::abs(dtm.heightAt(x, y)));
	EXPECT_LT(worst, 0.3) << "the clutter taken for ground";
	EXPECT_LT(std::abs(dtm.heightAt(4, 4)), 0.05);  // the open ground

	o.dtm_max_slope_deg = 0;  // the bound off: the median keeps the clutter
	EXPECT_GT(buildDtm(pts, o).heightAt(11, 11), 3.0);
}

// Stems among shrubs, a wall and branch-like clutter: walls and shrubs must
// not become trees.
TEST(Trees, SyntheticPlotWithShrubsAndWall)
{
	std::mt19937 rng(5);
	Pts pts;
	addGround(pts, rng, 20, 60000);
	std::uniform_real_distribution<double> pos(1.5, 18.5), dbh(0.10, 0.50);
	std::vector<Truth> truth;
	while (truth.size() < 20)
	{
		const Truth t{pos(rng), pos(rng), dbh(rng)};
		bool ok = t.x > 6 || t.y > 3;  // keep the wall's corner free
		for (const auto& q : truth)
			ok = ok && std::hypot(q.x - t.x, q.y - t.y) > 1.8;
		if (!ok) continue;
		truth.push_back(t);
		// Flat taper so DBH at 1.3 m is dbh.
		addStem(pts, rng, t.x, t.y, t.dbh / 2 + 0.01 * 1.3, 0.01, 6, 4000);
	}
	// Shrubs: dense blobs 0–1.8 m high, no circle in any slice.
	std::normal_distribution<double> g(0, 1);
	for (int s = 0; s < 12; s++)
	{
		const double cx = pos(rng), cy = pos(rng),
		             rad = 0.4 + 0.3 * (s % 3) / 2.0;
		for (int i = 0; i < 2500; i++)
		{
			Eigen::Vector3d d(g(rng), g(rng), g(rng));
			d = d.normalized() * rad *
			    std::cbrt(std::uniform_real_distribution<double>(0, 1)(rng));
			pts.emplace_back(
			    cx + d.x(), cy + d.y(),
			    groundZ(cx + d.x(), cy + d.y()) + 0.9 + 0.9 * d.z() / rad);
		}
	}
	// A wall 6 m long, 2.5 m high, along y = 1 from x = 0.5.
	std::uniform_real_distribution<double> wx(0.5, 6.5), wz(0, 2.5);
	for (int i = 0; i < 15000; i++)
	{
		const double x = wx(rng);
		pts.emplace_back(x, 1.0, groundZ(x, 1.0) + wz(rng));
	}
	// Branch-like clutter: thin horizontal sticks at 1–2.5 m.
	for (int b = 0; b < 15; b++)
	{
		const double cx = pos(rng), cy = pos(rng), cz = 1 + 0.1 * b, ang = b;
		for (int i = 0; i < 150; i++)
		{
			const double s = 1.5 * i / 150.0;
			pts.emplace_back(cx + s * std::cos(ang), cy + s * std::sin(ang),
			                 groundZ(cx, cy) + cz);
		}
	}
	TreeOptions o;
	const auto dtm = buildDtm(pts, o);
	TreeDetectionStats st;
	const auto found = detectTrees(pts, dtm, o, &st);
	double recall, precision, rmse;
	match(found, truth, recall, precision, rmse);
	std::printf(
	    "synthetic plot: %zu found, recall %.3f, precision %.3f, DBH RMSE %.1f "
	    "mm\n",
	    found.size(), recall, precision, 1e3 * rmse);
	EXPECT_GE(recall, 0.95);
	EXPECT_GE(precision, 0.999);
	EXPECT_LT(rmse, 0.01);
}

// TreeLS pine plot (10 × 10 m TLS). Manual inspection of the 1.2–1.4 m slice
// (doc/trees.md): about 18 stem cross-sections, a planted grid in rows x ≈ 0.4,
// 3.4, 6.3, 9.3 m, several cut by the plot border or seen from one side only.
// The stems confirmed by >= 4 slices (14 today; 12 before the section RMSE
// gate was widened for SLAM maps, which added the small stem at (3.46, 1.51)
// and the border stem at (0.28, 2.05)) are pinned with diameters estimated
// independently from the slice (algebraic fit on the hand-isolated cluster).
TEST(Trees, PinePlotRealData)
{
	const auto c = forest_slam::io::readLas(
	    std::string(FOREST_SLAM_SHARED_DIR) + "/data/treels/pine_plot.las");
	TreeOptions o;
	const auto found = detectTrees(c.xyz, buildDtm(c.xyz, o), o);
	EXPECT_GE(found.size(), 12u);
	EXPECT_LE(found.size(), 15u);
	for (const auto& t : found)
	{
		EXPECT_GE(t.record.dbh_m, 0.11);
		EXPECT_LE(t.record.dbh_m, 0.32);
		EXPECT_GT(t.record.height_m,
		          12.0);  // pines of ~17 m, tops seen by the TLS
		EXPECT_GE(t.record.n_points, 100u);
	}
	struct Manual
	{
		double x, y, dbh;
	};
	for (const Manual m : {Manual{9.26, 7.51, 0.293},
	                       {6.20, 1.02, 0.245},
	                       {6.43, 4.71, 0.254},
	                       {9.40, 1.24, 0.222},
	                       {0.50, 6.13, 0.231},
	                       {9.30, 5.44, 0.164},
	                       {3.44, 5.71, 0.157},
	                       {3.51, 7.68, 0.155},
	                       {9.36, 3.39, 0.131},
	                       {3.46, 1.51, 0.13}})
	{
		const DetectedTree* f = nullptr;
		for (const auto& t : found)
			if (std::hypot(t.record.x - m.x, t.record.y - m.y) < 0.1) f = &t;
		ASSERT_NE(f, nullptr) << "stem at " << m.x << ", " << m.y;
		EXPECT_NEAR(f->record.dbh_m, m.dbh, 0.025)
		    << "stem at " << m.x << ", " << m.y;
	}
}

TEST(Trees, SingleTreePine)
{
	const auto c = forest_slam::io::readLas(
	    std::string(FOREST_SLAM_SHARED_DIR) + "/data/treels/pine.las");
	TreeOptions o;
	const auto found = detectTrees(c.xyz, buildDtm(c.xyz, o), o);
	ASSERT_EQ(found.size(), 1u);
	EXPECT_GT(found[0].record.dbh_m, 0.20);
	EXPECT_LT(found[0].record.dbh_m, 0.32);
}

// TreeLS spruce: the low branches touch the stem, so every slice below 3 m
// is one wide cluster of branches and stem that fails as a section; the
// ring search inside such clusters finds the stem. Manual inspection of the
// slices (points within 25 cm of the densest spot, algebraic fit iterated
// on the points within 3 cm of the circle): a ring at (0.155, 0.005),
// DBH 25.1 cm at 1.3 m (24.4–26.1 cm over 1.0–1.6 m), RMSE 6 mm.
TEST(Trees, SingleTreeSpruceLowBranches)
{
	const auto c = forest_slam::io::readLas(
	    std::string(FOREST_SLAM_SHARED_DIR) + "/data/treels/spruce.las");
	TreeOptions o;
	const auto found = detectTrees(c.xyz, buildDtm(c.xyz, o), o);
	ASSERT_EQ(found.size(), 1u);
	EXPECT_NEAR(found[0].record.x, 0.155, 0.03);
	EXPECT_NEAR(found[0].record.y, 0.005, 0.03);
	EXPECT_NEAR(found[0].record.dbh_m, 0.251, 0.015);
	// Without the ring search the stem is not found (the open problem this
	// test pins).
	o.section_ring_search = false;
	EXPECT_TRUE(detectTrees(c.xyz, buildDtm(c.xyz, o), o).empty());
}
