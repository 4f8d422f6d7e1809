#pragma once
// Stem detection and DBH on a point cloud (paper §4.2 end, §6.2; issue 7).
//
//  1. heights above the local ground from a TerrainModel;
//  2. stacked horizontal slices (slice_min_m..slice_max_m): each clustered by
//     hierarchical k-means + neighbourhood merge, each cluster fitted with a
//     robust circle; plausible circles are stem sections;
//  3. sections linked upwards into stems with consistent centres, taper and
//     lean; shrubs (no circle), walls (no closed arc, too wide) and branches
//     (few slices) are rejected;
//  4. DBH from the 1.2–1.4 m band projected perpendicular to the stem axis,
//     statistical outlier removal (k=10, ω=0.4), robust circle fit.
#include <forest_slam/map/forest_map.h>
#include <forest_slam/trees/circle_fit.h>
#include <forest_slam/trees/terrain_model.h>
#include <forest_slam/trees/tree_options.h>

#include <Eigen/Core>

#include <vector>

namespace forest_slam::trees
{
/** Bits of map::TreeRecord::quality (0 = good). */
enum TreeQuality : uint8_t
{
	kPartialArc = 1,  ///< DBH arc coverage < good_arc_deg
	kHighRmse = 2,    ///< DBH fit RMSE > good_rmse_m
	kDbhFromSlices =
	    4,  ///< no usable 1.2–1.4 m fit: radius interpolated from slices
	kTopNotSeen = 8,  ///< no points above the slices: height_m = 0
};

struct StemSection
{
	int slice = 0;
	double height_m = 0;  ///< slice centre above ground
	Eigen::Vector2d centre = Eigen::Vector2d::Zero();
	double radius_m = 0, rmse_m = 0, arc_deg = 0;
	size_t n_points = 0;
};

struct DetectedTree
{
	map::TreeRecord record;
	double lean_deg = 0;
	Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  ///< unit, upwards
	std::vector<StemSection> sections;
};

struct TreeDetectionStats
{
	size_t slices = 0, slice_clusters = 0, sections = 0, chains = 0;
	size_t rejected_short = 0, rejected_shape = 0, rejected_points = 0,
	       rejected_duplicate = 0;
	size_t solid_rings = 0;  ///< DBH circles taken from fitSolidRing
};

/** Points near breast height kept per time segment of a SLAM run (the
 * same surface seen in two segments is two points), for the multi-view DBH
 * fit. `dirs` as detectTrees' view_dirs; `segment`: any id per point. */
struct SegmentedPoints
{
	std::vector<Eigen::Vector3d> pts;
	std::vector<Eigen::Vector3f> dirs;
	std::vector<uint32_t> segment;
	/** Optional: 0 (nearest) to 3, the horizontal range class of the
	 * scans that saw the point (TreeOptions::dbh_range_step_m). */
	std::vector<uint8_t> range_class;
};

/** Trees in `pts`, ids 1..N ordered by x then y. `view_dirs` (optional,
 * one per point): the mean viewing direction (sensor → point) of each
 * point, zero if unknown; where known, the DBH circle is refined with the
 * range noise along the rays (refineCircleAlongRays). `segments`
 * (optional): the breast-height points per time segment; if they hold two
 * or more segments near a stem, its DBH circle is finally refined on them
 * with one shift per segment (refineCircleSegments, prior
 * o.dbh_segment_shift_m). `point_times` (optional, one per point) [s]:
 * with o.dbh_drift_sigma_m_per_s > 0 the along-ray DBH fit lets the stem's
 * centre drift linearly in time (RayFitOptions). */
std::vector<DetectedTree> detectTrees(
    const std::vector<Eigen::Vector3d>& pts, const TerrainModel& terrain,
    const TreeOptions& o, TreeDetectionStats* stats = nullptr,
    const std::vector<Eigen::Vector3f>* view_dirs = nullptr,
    const SegmentedPoints* segments = nullptr,
    const std::vector<float>* point_times = nullptr);

/** The multi-view refinement of a DBH circle: the band points of `seg`
 * (already in the circle's 2D frame: `p`, unit directions or zero `dir`,
 * `segment`) within a residual gate of `c` are grouped by segment
 * (segments with fewer than max(3, min_dbh_points/2) points dropped) and
 * refineCircleSegments runs twice (the second time on the points within 4
 * robust scales of their segment's shifted circle). Returns the evaluation
 * of the consensus circle on the aligned points, or !ok (no segment left,
 * divergence, or a result outside [rmin, rmax] or more than 25 % from `c`).
 * Exposed for tests. */
CircleFitResult fitDbhSegments(const Points2D& p, const Points2D& dir,
                               const std::vector<uint32_t>& segment,
                               const Circle& c, double gate_m,
                               const TreeOptions& o, double rmin, double rmax);

/** Stem sections of one slice (exposed for tests and diagnostics). */
std::vector<StemSection> findSliceSections(const Points2D& slice_xy,
                                           int slice_index, double height_m,
                                           const TreeOptions& o,
                                           size_t* n_clusters = nullptr);

std::vector<map::TreeRecord> toRecords(const std::vector<DetectedTree>& trees);

}  // namespace forest_slam::trees
