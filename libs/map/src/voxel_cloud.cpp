#include <forest_slam/map/voxel_cloud.h>

#include <algorithm>
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
	voxel_m_ = s;
	inv_size_ = 1.f / s;
	clear();
}

size_t VoxelCloud::memoryBytes() const
{
	return voxels_.memoryBytes();
}

void VoxelCloud::insert(const Eigen::Vector3f& p)
{
	if (p.allFinite()) insert(keyOf(p), p);
}

void VoxelCloud::setVoxel(const VoxelKey& k, const Accum& a)
{
	if (a.count == 0)
		throw std::invalid_argument("VoxelCloud::setVoxel: zero count");
	voxels_[packed(k)] = a;
}

void VoxelCloud::appendCentroids(std::vector<Eigen::Vector3f>& out) const
{
	out.reserve(out.size() + voxels_.size());
	voxels_.forEach([&](uint64_t, const Accum& a)
	                { out.push_back(a.centroid()); });
}

bool VoxelCloud::centroidAt(const Eigen::Vector3f& p, Eigen::Vector3f& c) const
{
	const Accum* a = voxels_.find(packed(voxelKeyOf(p, inv_size_)));
	if (!a) return false;
	c = a->centroid();
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
				const Accum* a =
				    voxels_.find(packed({k.x + dx, k.y + dy, k.z + dz}));
				if (!a) continue;
				const Eigen::Vector3f c = a->centroid();
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
