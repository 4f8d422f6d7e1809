#include <forest_slam/outputs/dense_map.h>

#include <sys/mman.h>

#include <cmath>
#include <cstdint>
#include <stdexcept>

namespace forest_slam::outputs
{
namespace
{
constexpr uint64_t kEmpty = ~uint64_t(0);
constexpr int64_t kHalf = int64_t(1) << 20;  // 21 bits per axis

inline uint64_t mix(uint64_t x)
{
	x ^= x >> 33;
	x *= 0xff51afd7ed558ccdULL;
	x ^= x >> 33;
	x *= 0xc4ceb9fe1a85ec53ULL;
	x ^= x >> 33;
	return x;
}

/** Asks for transparent huge pages on a large table: each lookup lands on a
 * random page, and 4 kB pages make every one a TLB miss too. */
template <typename T>
void adviseHugePages(std::vector<T>& v)
{
	constexpr uintptr_t kHuge = uintptr_t(2) << 20;
	const auto b = reinterpret_cast<uintptr_t>(v.data());
	const auto e = b + v.size() * sizeof(T);
	const uintptr_t from = (b + kHuge - 1) & ~(kHuge - 1),
	                to = e & ~(kHuge - 1);
	if (to > from)
		madvise(reinterpret_cast<void*>(from), to - from, MADV_HUGEPAGE);
}

inline size_t slotOf(uint64_t key, size_t mask)
{
	return mix(key) & mask;
}

/** Packed voxel key (3 x 21 bits); false beyond 2^20 voxels of the origin. */
inline bool voxelKey(const Eigen::Vector3f& xyz, double inv, uint64_t& key)
{
	const int64_t i = static_cast<int64_t>(std::floor(xyz.x() * inv)) + kHalf;
	const int64_t j = static_cast<int64_t>(std::floor(xyz.y() * inv)) + kHalf;
	const int64_t k = static_cast<int64_t>(std::floor(xyz.z() * inv)) + kHalf;
	constexpr int64_t kLim = 2 * kHalf;
	if (i < 0 || j < 0 || k < 0 || i >= kLim || j >= kLim || k >= kLim)
		return false;
	key = (uint64_t(i) << 42) | (uint64_t(j) << 21) | uint64_t(k);
	return true;
}
}  // namespace

DenseMap::DenseMap(double voxel_m)
    : voxel_m_(voxel_m), inv_voxel_(1.0 / voxel_m)
{
	if (!(voxel_m > 0))
		throw std::invalid_argument("DenseMap: voxel size must be > 0");
	keys_.assign(1 << 12, kEmpty);
	index_.assign(keys_.size(), 0);
	mask_ = keys_.size() - 1;
}

size_t DenseMap::memoryBytes() const
{
	return points_.capacity() * sizeof(DensePoint) +
	       keys_.capacity() * sizeof(uint64_t) +
	       index_.capacity() * sizeof(uint32_t);
}

DensePoint* DenseMap::claim(const Eigen::Vector3f& xyz)
{
	uint64_t key;
	if (!xyz.allFinite() || !voxelKey(xyz, inv_voxel_, key)) return nullptr;
	if (2 * (points_.size() + 1) > keys_.size()) grow();
	size_t slot = slotOf(key, mask_);
	while (keys_[slot] != kEmpty)
	{
		if (keys_[slot] == key) return nullptr;
		slot = (slot + 1) & mask_;
	}
	keys_[slot] = key;
	index_[slot] = static_cast<uint32_t>(points_.size());
	points_.emplace_back();
	points_.back().xyz = xyz;
	return &points_.back();
}

void DenseMap::prefetch(const Eigen::Vector3f& xyz) const
{
	uint64_t key;
	if (!xyz.allFinite() || !voxelKey(xyz, inv_voxel_, key)) return;
	__builtin_prefetch(&keys_[slotOf(key, mask_)]);
}

bool DenseMap::add(const DensePoint& p)
{
	DensePoint* q = claim(p.xyz);
	if (q) *q = p;
	return q != nullptr;
}

void DenseMap::grow()
{
	std::vector<uint64_t> old_keys(keys_.size() * 2, kEmpty);
	std::vector<uint32_t> old_index(old_keys.size(), 0);
	old_keys.swap(keys_);
	old_index.swap(index_);
	adviseHugePages(keys_);
	mask_ = keys_.size() - 1;
	for (size_t s = 0; s < old_keys.size(); s++)
	{
		if (old_keys[s] == kEmpty) continue;
		size_t slot = slotOf(old_keys[s], mask_);
		while (keys_[slot] != kEmpty) slot = (slot + 1) & mask_;
		keys_[slot] = old_keys[s];
		index_[slot] = old_index[s];
	}
}

}  // namespace forest_slam::outputs
