#include <forest_slam/loop/keyframe_cloud.h>
#include <forest_slam/odometry/kdtree.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdint>
#include <unordered_set>

namespace forest_slam::loop
{
std::vector<Eigen::Vector3f> voxelFilter(
    const std::vector<Eigen::Vector3f>& pts, double voxel_m, double max_range_m)
{
	std::unordered_set<uint64_t> seen;
	seen.reserve(pts.size());
	std::vector<Eigen::Vector3f> out;
	const float r2 = static_cast<float>(max_range_m * max_range_m);
	const double inv = 1.0 / voxel_m;
	for (const auto& p : pts)
	{
		if (!p.allFinite() || p.squaredNorm() > r2) continue;
		const uint64_t m = (1u << 21) - 1;
		const uint64_t key =
		    ((static_cast<uint64_t>(
		          static_cast<int64_t>(std::floor(p.x() * inv))) &
		      m)
		     << 42) |
		    ((static_cast<uint64_t>(
		          static_cast<int64_t>(std::floor(p.y() * inv))) &
		      m)
		     << 21) |
		    (static_cast<uint64_t>(
		         static_cast<int64_t>(std::floor(p.z() * inv))) &
		     m);
		if (seen.insert(key).second) out.push_back(p);
	}
	return out;
}

NormalCloud withNormals(const std::vector<Eigen::Vector3f>& pts, int k,
                        double max_flatness)
{
	NormalCloud out;
	odometry::KdTree tree;
	tree.build(pts);
	std::vector<uint32_t> idx;
	std::vector<float> d2;
	const auto& P = tree.points();
	for (const auto& p : P)
	{
		if (tree.knn(p, static_cast<size_t>(k), idx, d2) <
		    static_cast<size_t>(k))
			continue;
		if (d2.back() > 1.5f * 1.5f) continue;  // sparse: no local plane
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
		out.points.push_back(p);
		out.normals.push_back(es.eigenvectors().col(0).cast<float>());
	}
	return out;
}

}  // namespace forest_slam::loop
