#pragma once
// Keyframe clouds for loop verification: voxel-filtered points in the
// keyframe's sensor frame, and submaps of neighbouring keyframes.
#include <Eigen/Geometry>

#include <vector>

namespace forest_slam::loop
{
/** One point per occupied voxel, the centroid of its points; points beyond
 * `max_range_m` from the origin and non-finite points dropped; voxels in the
 * order of their first point (deterministic). */
std::vector<Eigen::Vector3f> voxelFilter(
    const std::vector<Eigen::Vector3f>& pts, double voxel_m,
    double max_range_m);

/** Points with unit normals (planar neighbourhoods only), for
 * point-to-plane ICP targets. */
struct NormalCloud
{
	std::vector<Eigen::Vector3f> points, normals;
};
/** Normals from the k nearest neighbours (PCA); points whose neighbourhood
 * is not planar enough (smallest / middle eigenvalue above `max_flatness`:
 * foliage, whose hits change with the view), a line (a single ring) or too
 * sparse are dropped. Points in their input order; the same for any
 * number of threads (the caller's and threads-1 helpers, core::
 * parallelRanges). */
NormalCloud withNormals(const std::vector<Eigen::Vector3f>& pts, int k = 10,
                        double max_flatness = 0.3, int threads = 1);

}  // namespace forest_slam::loop
