#include <forest_slam/core/flat_hash_map.h>
#include <forest_slam/core/parallel_for.h>
#include <forest_slam/loop/keyframe_cloud.h>
#include <forest_slam/odometry/kdtree.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace forest_slam::loop
{
std::vector<Eigen::Vector3f> voxelFilter(
    const std::vector<Eigen::Vector3f>& pts, double voxel_m, double max_range_m)
{
	// The centroid of each voxel, not its first point: a scan lists its
	// points in firing order, so the first point of a voxel is where the
	// sweep entered it, and every voxel's point shifted the same way round
	// the sensor. Loop closures between such clouds came out turned by
	// +0.013 to +0.016 deg on average (forest-sim robot, 117 closures per
	// run; doc/backend.md "Keyframe clouds: voxel centroids").
	// Voxels in the order of their first point, which is why this is not
	// map::VoxelCloud (same centroids, its table's order): the ICP thins
	// its source evenly along this order, and with the table's order
	// BackEnd.RefusesTheNeighbouringRowOfAPlantation accepted a closure 3 m
	// off.
	// Key -> index of the voxel's sum: a flat table (std::unordered_map's
	// node per voxel was 1.2 % of a robot run's CPU in this function).
	core::FlatHashMap<uint32_t> slot;
	slot.reserve(pts.size());
	std::vector<Eigen::Vector3d> sum;
	std::vector<uint32_t> count;
	const float r2 = static_cast<float>(max_range_m * max_range_m);
	const double inv = 1.0 / voxel_m;
	auto cell = [&](float v)
	{ return static_cast<int64_t>(std::floor(v * inv)); };
	for (const auto& p : pts)
	{
		if (!p.allFinite() || p.squaredNorm() > r2) continue;
		const uint64_t key =
		    core::packCellKey(cell(p.x()), cell(p.y()), cell(p.z()));
		bool fresh = false;
		uint32_t& i = slot.tryEmplace(key, &fresh);
		if (fresh)
		{
			i = static_cast<uint32_t>(sum.size());
			sum.emplace_back(Eigen::Vector3d::Zero());
			count.push_back(0);
		}
		sum[i] += p.cast<double>();
		count[i]++;
	}
	std::vector<Eigen::Vector3f> out(sum.size());
	for (size_t i = 0; i < sum.size(); i++)
		out[i] = (sum[i] / count[i]).cast<float>();
	return out;
}

NormalCloud withNormals(const std::vector<Eigen::Vector3f>& pts, int k,
                        double max_flatness, int threads)
{
	const float kSparseBound =
	    std::nextafter(1.5f * 1.5f, std::numeric_limits<float>::infinity());
	odometry::KdTree tree;
	tree.build(pts);
	const auto& P = tree.points();
	// Each point's normal on its own (a third of a loop verification's
	// CPU): shared out in chunks, kept in the points' order.
	std::vector<Eigen::Vector3f> normal(P.size());
	std::vector<uint8_t> planar(P.size(), 0);
	struct Scratch
	{
		std::vector<uint32_t> idx;
		std::vector<float> d2;
	};
	std::vector<Scratch> scratch(static_cast<size_t>(std::max(1, threads)));
	core::parallelRanges(
	    P.size(), threads, 512,
	    [&](size_t b, size_t e, int w)
	    {
		    auto& idx = scratch[w].idx;
		    auto& d2 = scratch[w].d2;
		    for (size_t j = b; j < e; j++)
		    {
			    // Sparse (the k-th neighbour beyond 1.5 m): no local
			    // plane. The bound (just above, a neighbour at 1.5 m is
			    // kept) prunes the search.
			    if (tree.knnBelow(P[j], static_cast<size_t>(k), kSparseBound,
			                      idx, d2) < static_cast<size_t>(k))
				    continue;
			    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
			    for (auto i : idx) mean += P[i].cast<double>();
			    mean /= idx.size();
			    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
			    for (auto i : idx)
			    {
				    const Eigen::Vector3d d = P[i].cast<double>() - mean;
				    C += d * d.transpose();
			    }
			    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
			    es.computeDirect(C);
			    const auto ev = es.eigenvalues();
			    // Planar enough: foliage (volumetric) is dropped.
			    if (!(ev[1] > 0) || ev[0] > max_flatness * ev[1]) continue;
			    normal[j] = es.eigenvectors().col(0).cast<float>();
			    planar[j] = 1;
		    }
	    });
	NormalCloud out;
	for (size_t j = 0; j < P.size(); j++)
		if (planar[j])
		{
			out.points.push_back(P[j]);
			out.normals.push_back(normal[j]);
		}
	return out;
}

}  // namespace forest_slam::loop
