#include <forest_slam/core/memory.h>
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

void VoxelCloud::clear()
{
	slots_.clear();
	slots_.shrink_to_fit();
	size_ = 0;
}

size_t VoxelCloud::memoryBytes() const
{
	return core::vectorBytes(slots_);
}

void VoxelCloud::grow()
{
	std::vector<Slot> old(std::max<size_t>(64, 2 * slots_.size()));
	old.swap(slots_);
	const size_t mask = slots_.size() - 1;
	for (const Slot& s : old)
	{
		if (s.acc.count == 0) continue;
		size_t i = VoxelKeyHash()(s.key) & mask;
		while (slots_[i].acc.count != 0) i = (i + 1) & mask;
		slots_[i] = s;
	}
}

VoxelCloud::Accum& VoxelCloud::slotFor(const VoxelKey& k)
{
	if (8 * (size_ + 1) > 5 * slots_.size()) grow();
	const size_t mask = slots_.size() - 1;
	size_t i = VoxelKeyHash()(k) & mask;
	for (;; i = (i + 1) & mask)
	{
		Slot& s = slots_[i];
		if (s.acc.count == 0)
		{
			s.key = k;
			size_++;
			return s.acc;
		}
		if (s.key == k) return s.acc;
	}
}

const VoxelCloud::Accum* VoxelCloud::find(const VoxelKey& k) const
{
	if (slots_.empty()) return nullptr;
	const size_t mask = slots_.size() - 1;
	for (size_t i = VoxelKeyHash()(k) & mask;; i = (i + 1) & mask)
	{
		const Slot& s = slots_[i];
		if (s.acc.count == 0) return nullptr;
		if (s.key == k) return &s.acc;
	}
}

void VoxelCloud::insert(const Eigen::Vector3f& p)
{
	if (!p.allFinite()) return;
	auto& a = slotFor(voxelKeyOf(p, inv_size_));
	a.sum += p;
	a.count++;
}

void VoxelCloud::setVoxel(const VoxelKey& k, const Accum& a)
{
	if (a.count == 0)
		throw std::invalid_argument("VoxelCloud::setVoxel: zero count");
	slotFor(k) = a;
}

void VoxelCloud::appendCentroids(std::vector<Eigen::Vector3f>& out) const
{
	out.reserve(out.size() + size_);
	forEachVoxel([&](const VoxelKey&, const Accum& a)
	             { out.push_back(a.centroid()); });
}

bool VoxelCloud::centroidAt(const Eigen::Vector3f& p, Eigen::Vector3f& c) const
{
	const Accum* a = find(voxelKeyOf(p, inv_size_));
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
				const Accum* a = find({k.x + dx, k.y + dy, k.z + dz});
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
