#pragma once
// A point cloud kept by a voxel filter: each voxel stores the running sum of
// the points that fell into it, so its representative is the exact centroid
// (the paper's §4.5 VoxelGrid behaviour) however many scans fed it.
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
		// The three 21-bit-folded coordinates in one word, then a 64-bit
		// finaliser (splitmix64): neighbouring voxels land far apart, which
		// the open-addressing table of VoxelCloud needs (linear probing
		// degrades on runs of nearby hashes).
		uint64_t h = (static_cast<uint64_t>(static_cast<uint32_t>(k.x)) << 42) ^
		             (static_cast<uint64_t>(static_cast<uint32_t>(k.y)) << 21) ^
		             static_cast<uint64_t>(static_cast<uint32_t>(k.z));
		h ^= h >> 30;
		h *= 0xbf58476d1ce4e5b9ull;
		h ^= h >> 27;
		h *= 0x94d049bb133111ebull;
		h ^= h >> 31;
		return static_cast<size_t>(h);
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
	size_t size() const { return size_; }
	bool empty() const { return size_ == 0; }
	void clear();
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
		for (const Slot& s : slots_)
			if (s.acc.count != 0) f(s.key, s.acc);
	}
	/** Restores one voxel (deserialization); replaces an existing one. */
	void setVoxel(const VoxelKey& k, const Accum& a);

   private:
	// Open addressing with linear probing in a power-of-two table, at most
	// 5/8 full; an empty slot has count 0. Each scan adds tens of thousands
	// of points, one lookup each: std::unordered_map's node chasing was the
	// largest single cost of a mapping run (17 % of the CPU, perf).
	struct Slot
	{
		VoxelKey key;
		Accum acc;
	};
	Accum& slotFor(const VoxelKey& k);
	const Accum* find(const VoxelKey& k) const;
	void grow();

	float voxel_m_ = 0.2f, inv_size_ = 5.f;
	std::vector<Slot> slots_;
	size_t size_ = 0;
};

}  // namespace forest_slam::map
