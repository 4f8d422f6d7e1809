#pragma once
// Robust circle fit for stem cross-sections (paper §4.2 "fitting a circle";
// issue 7: algebraic start, geometric least squares with a robust loss,
// RANSAC against branch stubs, unbiased on partial arcs).
#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace forest_slam::trees
{
using Points2D =
    std::vector<Eigen::Vector2d, Eigen::aligned_allocator<Eigen::Vector2d>>;

struct Circle
{
	Eigen::Vector2d centre = Eigen::Vector2d::Zero();
	double radius_m = 0;
};

struct CircleFitOptions
{
	double min_radius_m = 0.01;
	double max_radius_m = 1.0;
	int ransac_iterations = 300;  ///< at most (fewer once a sample is good)
	double ransac_inlier_m = 0.015;
	uint32_t seed = 1;
	double arc_bin_deg = 5;
};

struct CircleFitResult
{
	bool ok = false;
	Circle circle;
	double rmse_m = 0;            ///< geometric residuals of the inliers
	double scale_m = 0;           ///< robust residual scale (1.4826 MAD)
	size_t n_inliers = 0;         ///< |residual| <= 3 scale
	double arc_coverage_deg = 0;  ///< angular bins holding an inlier
};

/** Kåsa's algebraic fit (linear least squares on x²+y²+Dx+Ey+F); cheap and
 * always defined, but shrinks the radius on partial arcs: only a start.
 * Returns false for fewer than 3 points or collinear points. */
bool fitCircleKasa(const Points2D& p, Circle& out);
/** The circle through three points, in closed form (false: collinear). */
bool circleThrough3(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                    const Eigen::Vector2d& c, Circle& out);

/** Geometric (orthogonal distance) fit by Gauss–Newton/Levenberg–Marquardt
 * with Tukey-biweight IRLS; the residual scale is re-estimated from the MAD
 * each iteration, so inliers keep full, symmetric weight (no truncation bias)
 * while stubs and leaves beyond ~4.7 σ get zero weight. */
bool refineCircleGeometric(const Points2D& p, Circle& c,
                           double min_scale_m = 0.002, int max_iterations = 50);

/** RANSAC iterations that draw, with 99.9 % confidence, at least one
 * all-inlier 3-point sample when a share `inlier_share` of the points are
 * inliers; at least `min_iterations`, at most `max_iterations`. */
int ransacIterationsNeeded(double inlier_share, int min_iterations,
                           int max_iterations);

/** The full robust fit: candidates from Kåsa on all points and from RANSAC on
 * 3-point samples, each refined geometrically; the one with the lower robust
 * cost wins. */
CircleFitResult fitCircleRobust(const Points2D& p, const CircleFitOptions& o);

/** Scale, inliers, RMSE and arc coverage of circle `c` on `p`, as
 * fitCircleRobust reports them. */
CircleFitResult evaluateCircle(const Points2D& p, const Circle& c,
                               const CircleFitOptions& o);

/** The fit f of points p checked against a reference circle seen over
 * `reference_arc_deg` (a stem's slices above and below): if f sees less
 * than half that arc (points within 2 ransac_inlier_m) and its radius is
 * more than a quarter off the reference's, f is taken for a small circle
 * through part of the ring (a local optimum of the robust fit) and the fit
 * starts again from the reference, on the points within 4 ransac_inlier_m
 * of it. Returns the new circle if it sees at least as much of p (a band
 * of a few points, where both see the same short arc, is better read by
 * the slices); else f (also when the new fit fails, leaves the radius
 * range or has fewer than min_points points). */
CircleFitResult checkAgainstReference(
    const Points2D& p, const CircleFitResult& f, const Circle& reference,
    double reference_arc_deg, const CircleFitOptions& o, size_t min_points);
/** Geometric fit for range noise along the rays (lidar): the residual of
 * point p_i seen along the unit direction d_i (sensor → point, in the plane
 * of the circle) is the signed distance t_i along the ray from the circle's
 * near surface to the point. For the true circle t_i is exactly the range
 * error, so the estimate stays unbiased where orthogonal distances are not:
 * near the silhouette range noise moves points along the tangent, always
 * outwards, and a free-centre orthogonal fit of a one-sided arc comes out
 * several mm small (r = 10 cm, σ = 2.5 cm). Rays that miss the circle get
 * zero weight. Gauss–Newton / Levenberg–Marquardt with Tukey-biweight IRLS
 * and MAD scale (as refineCircleGeometric), started from `c`. Returns false
 * if fewer than 3 rays hit or the fit diverges. */
bool refineCircleAlongRays(const Points2D& p, const Points2D& dir, Circle& c,
                           double min_scale_m = 0.002, int max_iterations = 50);

/** Options of the along-ray fit beyond the defaults of the overload above. */
struct RayFitOptions
{
	/** Per point (e.g. the mean time of a voxel's scan points) [s]; with
	 * drift_sigma_m_per_s > 0 the circle's centre moves linearly in time,
	 * c + v (t - t̄) with t̄ the weighted mean time: the apparent drift of
	 * a stem in a map whose poses drift while the stem is seen (an
	 * odometry scale error squashes a stem passed by along the walk). `c`
	 * is then the circle at t̄. */
	const std::vector<double>* times = nullptr;
	double drift_sigma_m_per_s = 0;  ///< Gaussian prior on v per axis
	/** Points more than this apart in time (sorted) are separate passes,
	 * each with its own v about its own mean time: a stem passed by twice,
	 * in other directions, is squashed along each pass, which one v
	 * across minutes cannot follow [s]. */
	double pass_gap_s = 30;
	double min_scale_m = 0.002;
	int max_iterations = 50;
};
/** `drift` (optional): the fitted v of the pass with the most points
 * (zero if not estimated). */
bool refineCircleAlongRays(const Points2D& p, const Points2D& dir, Circle& c,
                           const RayFitOptions& o,
                           Eigen::Vector2d* drift = nullptr);

/** Multi-view fit of one stem seen in several time segments of a SLAM run,
 * each with its own small pose error: the points of segment g lie on the
 * circle (centre + s_g, r) with a common radius and a segment shift s_g
 * under a Gaussian prior of `shift_sigma_m` per axis. A pose error then
 * moves a segment's ring instead of blurring the union (a blurred or doubled
 * ring makes one circle too large). Residuals along the rays where `dir` is
 * non-zero (as refineCircleAlongRays; a missed ray costs the Tukey maximum),
 * orthogonal elsewhere; Tukey-biweight IRLS with MAD scale and Levenberg–
 * Marquardt, started from `c` with zero shifts. `segment`: any ids, one per
 * point. On success `c` is the consensus circle and `shifts` (optional)
 * receives each point's segment shift. Returns false for fewer than 3
 * points, sizes that differ, shift_sigma_m <= 0 or divergence. */
bool refineCircleSegments(const Points2D& p, const Points2D& dir,
                          const std::vector<uint32_t>& segment,
                          double shift_sigma_m, Circle& c,
                          Points2D* shifts = nullptr,
                          double min_scale_m = 0.002, int max_iterations = 50);

/** A stem is solid: foliage around it (a shrub at its foot) puts points
 * outside its ring, never inside, and a robust fit takes that foliage into
 * a ring too large. This fit scores circles by the points within `band_m`
 * of them (weight 1 - (r/band)²) minus one per point farther than `band_m`
 * inside, over `start` and `iterations` 3-point samples (radius 0.4 to
 * 1.05 × start's, centre within start's radius of start's), then refines
 * the best on the points within `band_m` (Kåsa + refineCircleGeometric,
 * five rounds). Returns `start` unchanged if nothing scores better.
 * Deterministic for a given `seed`. */
Circle fitSolidRing(const Points2D& p, const Circle& start, double band_m,
                    int iterations, unsigned seed);

/** Radius of a stem from the lateral spread of the rays that hit it. Rays
 * evenly spaced in angle hit a circle of radius r seen from afar at lateral
 * offsets u (the ray line's distance from the centre) spread evenly over
 * [-r, r], so r = sqrt(3 mean u²): range noise moves a point along its ray,
 * never across, so it leaves this estimate alone (on a small stem it is as
 * large as the radius and pins the fitted radius only loosely). Lateral
 * blur (pose errors) inflates it; a near stem's voxels, each merging many
 * rays at its front, sample u unevenly and deflate it: the stem detector
 * uses it on small stems only. Points with a zero `dir` (unit, as
 * refineCircleAlongRays) or farther than radius + `reach_m` from the
 * centre (clutter) are left out; NaN if fewer than `min_points` remain.
 * The cut also drops the front's points with the largest range errors
 * (small |u|): under range noise sigma, a reach of 1.6 sigma reads a 5 cm
 * radius ~1-2 mm large. */
double silhouetteRadius(const Points2D& p, const Points2D& dir, const Circle& c,
                        double reach_m, size_t min_points);

/** Degrees of the circle seen by `p`: bins of `bin_deg` holding a point
 * within `max_residual_m` of the circle. */
double arcCoverageDeg(const Points2D& p, const Circle& c, double max_residual_m,
                      double bin_deg);

}  // namespace forest_slam::trees
