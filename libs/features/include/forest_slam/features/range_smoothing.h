#pragma once
// Range smoothing along the rings, for the odometry's matching only.
//
// A VLP-16's returns carry ~2.5 cm of range noise; on a stem, whose surface
// curves away from every view, noisy returns matched to a map of noisy
// returns from other views shorten the estimated path (forest-sim: the
// whole scale error comes with the noise on the stems' returns,
// doc/odometry.md). A quadratic Savitzky-Golay filter over consecutive
// firings of a ring that hit the same object halves the noise's variance
// (5 firings, h = 2; a third is left with 7) and keeps a stem's bulge: a
// parabola is fitted, not a mean.
#include <forest_slam/features/feature_extractor.h>

#include <Eigen/Core>
#include <vector>

namespace forest_slam::features
{
/** Each point's position with its range smoothed along its ring, in the
 * input's order and frame (the direction is kept). A run (consecutive
 * firings on one object) of at least 2h+1 points is smoothed but for its
 * two ends (a stem's silhouette is not extrapolated); a point fewer than h
 * firings from an end takes the fit of the window moved inwards. Shorter
 * runs, non-finite points and points of no cluster are returned
 * unchanged. */
std::vector<Eigen::Vector3f> smoothRanges(
    const std::vector<FeatureInputPoint>& pts, const RangeSmoothingOptions& o);
/** The same, with the scan's ring lines already built (ringLines(pts)). */
std::vector<Eigen::Vector3f> smoothRanges(
    const std::vector<FeatureInputPoint>& pts, const RingLines& lines,
    const RangeSmoothingOptions& o);

}  // namespace forest_slam::features
