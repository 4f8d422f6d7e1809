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
};

/** Trees in `pts`, ids 1..N ordered by x then y. `view_dirs` (optional,
 * one per point): the mean viewing direction (sensor → point) of each
 * point, zero if unknown; where known, the DBH circle is refined with the
 * range noise along the rays (refineCircleAlongRays). */
std::vector<DetectedTree> detectTrees(
    const std::vector<Eigen::Vector3d>& pts, const TerrainModel& terrain,
    const TreeOptions& o, TreeDetectionStats* stats = nullptr,
    const std::vector<Eigen::Vector3f>* view_dirs = nullptr);

/** Stem sections of one slice (exposed for tests and diagnostics). */
std::vector<StemSection> findSliceSections(const Points2D& slice_xy,
                                           int slice_index, double height_m,
                                           const TreeOptions& o,
                                           size_t* n_clusters = nullptr);

std::vector<map::TreeRecord> toRecords(const std::vector<DetectedTree>& trees);

}  // namespace forest_slam::trees
