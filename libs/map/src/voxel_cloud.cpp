#include <forest_slam/core/memory.h>
#include <forest_slam/map/voxel_cloud.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace forest_slam::map
{
void VoxelCloud::setVoxelSize(float s)
{
	if (!(s > 0) || !std::isfinite(s))
		throw std::invalid_argument("voxel size must be > 0, got " +
		                            std::to_string(s));
	size_ = s;
	inv_size_ = 1.f / s;
	voxels_.clear();
}

size_t VoxelCloud::memoryBytes() const
{
	return core::hashMapBytes(voxels_);
}

void VoxelCloud::insert(const Eigen::Vector3f& p)
{
	if (!p.allFinite()) return;
	auto& a = voxels_[voxelKeyOf(p, inv_size_)];
	a.sum += p;
	a.count++;
}

void VoxelCloud::appendCentroids(std::vector<Eigen::Vector3f>& out) const
{
	out.reserve(out.size() + voxels_.size());
	for (const auto& kv : voxels_) out.push_back(kv.second.centroid());
}

bool VoxelCloud::centroidAt(const Eigen::Vector3f& p, Eigen::Vector3f& c) const
{
	const auto it = voxels_.find(voxelKeyOf(p, inv_size_));
	if (it == voxels_.end()) return false;
	c = it->second.centroid();
	return true;
}

bool VoxelCloud::nearestAround(const Eigen::Vector3f& p, Eigen::Vector3f& best,
							   float& best_sq) const
{
	const VoxelKey k = voxelKeyOf(p, inv_size_);
	bool found = false;
	best_sq = std::numeric_limits<float>::max();
	for (int dx = -1; dx <= 1; dx++)
		for (int dy = -1; dy <= 1; dy++)
			for (int dz = -1; dz <= 1; dz++)
			{
				const auto it = voxels_.find({k.x + dx, k.y + dy, k.z + dz});
				if (it == voxels_.end()) continue;
				const Eigen::Vector3f c = it->second.centroid();
				const float d = (c - p).squaredNorm();
				if (d < best_sq)
				{
					best_sq = d;
					best = c;
					found = true;
				}
			}
	return found;
}

}  // namespace forest_slam::map
