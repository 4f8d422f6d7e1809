#pragma once
// A point cloud kept by a voxel filter: each voxel stores the running sum of
// the points that fell into it, so its representative is the exact centroid
// (the paper's §4.5 VoxelGrid behaviour) however many scans fed it.
#include <forest_slam/core/flat_hash_map.h>

#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <vector>

namespace forest_slam::map
{
struct VoxelKey
{
	int32_t x = 0, y = 0, z = 0;
	bool operator==(const VoxelKey& o) const
	{
		return x == o.x && y == o.y && z == o.z;
	}
};

struct VoxelKeyHash
{
	size_t operator()(const VoxelKey& k) const
	{
		return static_cast<size_t>(
		    core::mixKey(core::packCellKey(k.x, k.y, k.z)));
	}
};

inline VoxelKey voxelKeyOf(const Eigen::Vector3f& p, float inv_size)
{
	return {static_cast<int32_t>(std::floor(p.x() * inv_size)),
	        static_cast<int32_t>(std::floor(p.y() * inv_size)),
	        static_cast<int32_t>(std::floor(p.z() * inv_size))};
}

class VoxelCloud
{
   public:
	explicit VoxelCloud(float voxel_size_m = 0.2f)
	{
		setVoxelSize(voxel_size_m);
	}
	/** Changing the size clears the cloud. */
	void setVoxelSize(float voxel_size_m);
	float voxelSize() const { return voxel_m_; }

	void insert(const Eigen::Vector3f& p);
	/** Bulk insertion in two steps: the key of a finite point, then the
	 * point with its key; in between the caller prefetches the keys a few
	 * points ahead (FlatHashMap::prefetch). Same result as insert(). */
	uint64_t keyOf(const Eigen::Vector3f& p) const
	{
		return packed(voxelKeyOf(p, inv_size_));
	}
	void insert(uint64_t key, const Eigen::Vector3f& p)
	{
		auto& a = voxels_[key];
		a.sum += p;
		a.count++;
	}
	void prefetch(uint64_t key) const { voxels_.prefetch(key); }
	size_t size() const { return voxels_.size(); }
	bool empty() const { return voxels_.empty(); }
	void clear() { voxels_.clear(); }
	/** Heap bytes held (estimate, core/memory.h). */
	size_t memoryBytes() const;

	/** Centroid of every voxel (unordered). */
	void appendCentroids(std::vector<Eigen::Vector3f>& out) const;
	/** Centroid of the voxel holding `p`, if any. */
	bool centroidAt(const Eigen::Vector3f& p, Eigen::Vector3f& c) const;
	/** Nearest centroid among the 27 voxels around `p`; false if none. */
	bool nearestAround(const Eigen::Vector3f& p, Eigen::Vector3f& best,
	                   float& best_sq_dist) const;

	struct Accum
	{
		Eigen::Vector3f sum = Eigen::Vector3f::Zero();
		uint32_t count = 0;
		Eigen::Vector3f centroid() const
		{
			return sum / static_cast<float>(count);
		}
	};
	/** Calls f(key, accum) for every voxel, in table order (deterministic
	 * for a given insertion sequence, not sorted). */
	template <class F>
	void forEachVoxel(F&& f) const
	{
		voxels_.forEach(
		    [&](uint64_t k, const Accum& a)
		    {
			    f(VoxelKey{core::unpackCellIndex(k, 0),
			               core::unpackCellIndex(k, 1),
			               core::unpackCellIndex(k, 2)},
			      a);
		    });
	}
	/** Adds a voxel's points (sum and count) to voxel `key` (keyOf a point
	 * inside it): merging moved voxels. */
	void add(uint64_t key, const Accum& a)
	{
		auto& v = voxels_[key];
		v.sum += a.sum;
		v.count += a.count;
	}
	/** Restores one voxel (deserialization); replaces an existing one. */
	void setVoxel(const VoxelKey& k, const Accum& a);

   private:
	static uint64_t packed(const VoxelKey& k)
	{
		return core::packCellKey(k.x, k.y, k.z);
	}
	// Voxel indices in 21 bits per axis: +-100 km at 0.1 m, far beyond a
	// stand in the map frame (origin at the first lidar position).
	float voxel_m_ = 0.2f, inv_size_ = 5.f;
	core::FlatHashMap<Accum> voxels_;
};

}  // namespace forest_slam::map
