#pragma once
// Clustering of one horizontal slice (paper §4.2): hierarchical k-means with
// branching factor k splits the points until every leaf holds <= σ points
// (libs/cluster, the same implementation the odometry front-end uses), then a
// neighbourhood criterion joins leaves whose points come closer than
// link_distance_m, so one stem split by k-means is one object again.
#include <forest_slam/trees/circle_fit.h>

#include <cstdint>
#include <vector>

namespace forest_slam::trees
{
/** One point per occupied `cell_m` square: the mean of its points (a slice
 * of a voxelised map stacks ~10 points on every spot of a stem). Sorted by
 * cell, deterministic. If `cell_of` is given it receives, for every input
 * point, the index of its square's output point. */
Points2D thinToCells(const Points2D& p, double cell_m,
                     std::vector<uint32_t>* cell_of = nullptr);

/** Leaf index of each point of `p` (0..n_leaves-1): cluster::hierarchicalKMeans
 * on the points centred on their mean (float precision on georeferenced
 * clouds), without its small-cluster merge. Deterministic. */
std::vector<int> sliceKMeansLeaves(const Points2D& p, int branching,
                                   int leaf_points);

/** Clusters (lists of point indices) after joining leaves linked by any pair
 * of points within link_m; largest first. */
std::vector<std::vector<size_t>> mergeLeavesByNeighbourhood(
    const Points2D& p, const std::vector<int>& leaf, double link_m);

}  // namespace forest_slam::trees
