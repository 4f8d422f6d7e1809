#include <forest_slam/core/memory.h>
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
constexpr uint64_t kAxis = (uint64_t(1) << 21) - 1;
constexpr size_t kFirstSlots = 1 << 8;  // small tiles stay small
/** Most slots in use per table, 3 in 4: a block already in the table (most
 * claims) is found in 2.5 probes on average at that load. */
inline bool overLoad(size_t used, size_t slots)
{
	return 4 * used > 3 * slots;
}

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

/** The block of a packed voxel key: each axis' index / 4 (the indices are
 * offset by kHalf, a multiple of 4, so the blocks align with the grid). */
inline uint64_t blockKeyOf(uint64_t key)
{
	constexpr uint64_t kKeep = ~((uint64_t(3) << 42) | (uint64_t(3) << 21) | 3);
	return (key & kKeep) >> 2;
}
/** The voxel's bit in its block's mask. */
inline uint64_t voxelBitOf(uint64_t key)
{
	const unsigned i = unsigned(key >> 42) & 3, j = unsigned(key >> 21) & 3,
	               k = unsigned(key) & 3;
	return uint64_t(1) << (i * 16 + j * 4 + k);
}

/** Linear probing: the slot of block `bk` in `table`, or the empty slot
 * where it goes. */
template <typename Slot>
Slot& probe(std::vector<Slot>& table, size_t mask, uint64_t bk)
{
	size_t slot = slotOf(bk, mask);
	while (table[slot].key != bk && table[slot].key != kEmpty)
		slot = (slot + 1) & mask;
	return table[slot];
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

/** Floor division (voxel indices are negative west/south of the origin). */
inline int64_t floorDiv(int64_t a, int64_t b)
{
	return a / b - ((a % b != 0) && ((a < 0) != (b < 0)));
}
}  // namespace

DenseMap::DenseMap(double voxel_m, double tile_m)
    : voxel_m_(voxel_m), inv_voxel_(1.0 / voxel_m), tile_vox_(0)
{
	if (!(voxel_m > 0))
		throw std::invalid_argument("DenseMap: voxel size must be > 0");
	// Tiles are whole voxels wide, so a voxel never straddles two tiles.
	if (tile_m > 0)
		tile_vox_ = std::max<int64_t>(1, std::llround(tile_m / voxel_m));
}

uint64_t DenseMap::tileKeyOf(uint64_t key) const
{
	if (tile_vox_ == 0) return 0;
	const int64_t i = int64_t((key >> 42) & kAxis) - kHalf;
	const int64_t j = int64_t((key >> 21) & kAxis) - kHalf;
	const int64_t ti = floorDiv(i, tile_vox_), tj = floorDiv(j, tile_vox_);
	return (uint64_t(uint32_t(int32_t(ti))) << 32) | uint32_t(int32_t(tj));
}

DenseMap::Tile* DenseMap::findTile(uint64_t key) const
{
	const uint64_t tk = tileKeyOf(key);
	if (have_last_ && tk == last_key_) return tiles_[last_tile_].get();
	const auto it = by_key_.find(tk);
	if (it == by_key_.end()) return nullptr;
	have_last_ = true;
	last_key_ = tk;
	last_tile_ = it->second;
	return tiles_[it->second].get();
}

DenseMap::Tile& DenseMap::tileFor(uint64_t key)
{
	if (Tile* t = findTile(key)) return *t;
	const uint64_t tk = tileKeyOf(key);
	auto t = std::make_unique<Tile>();
	t->tx = int32_t(uint32_t(tk >> 32));
	t->ty = int32_t(uint32_t(tk));
	t->blocks.resize(kFirstSlots);
	t->mask = kFirstSlots - 1;
	by_key_.emplace(tk, static_cast<uint32_t>(tiles_.size()));
	tiles_.push_back(std::move(t));
	have_last_ = true;
	last_key_ = tk;
	last_tile_ = static_cast<uint32_t>(tiles_.size() - 1);
	return *tiles_.back();
}

size_t DenseMap::memoryBytes() const
{
	size_t n = core::hashMapBytes(by_key_) + core::vectorBytes(tiles_);
	for (const auto& t : tiles_)
		n += sizeof(Tile) + core::vectorBytes(t->points) +
		     core::vectorBytes(t->blocks) + core::vectorBytes(t->chunks);
	return n;
}

size_t DenseMap::spilledBytes() const
{
	size_t n = 0;
	for (const auto& t : tiles_)
		for (const auto& c : t->chunks) n += c.count * sizeof(DensePoint);
	return n;
}

size_t DenseMap::pointsInMemory() const
{
	size_t n = 0;
	for (const auto& t : tiles_) n += t->points.size();
	return n;
}

size_t DenseMap::tilesSpilled() const
{
	size_t n = 0;
	for (const auto& t : tiles_) n += t->spilled ? 1 : 0;
	return n;
}

DensePoint* DenseMap::claim(const Eigen::Vector3f& xyz)
{
	if (moved_)
		throw std::logic_error("DenseMap: points added after transformPoints");
	uint64_t key;
	if (!xyz.allFinite() || !voxelKey(xyz, inv_voxel_, key)) return nullptr;
	Tile& t = tileFor(key);
	if (t.spilled) reload(t);
	return claimIn(t, key, xyz);
}

DensePoint* DenseMap::claimIn(Tile& t, uint64_t key, const Eigen::Vector3f& xyz)
{
	if (!insertKey(t, key)) return nullptr;
	t.points.emplace_back();
	t.points.back().xyz = xyz;
	t.count++;
	size_++;
	return &t.points.back();
}

bool DenseMap::insertKey(Tile& t, uint64_t key) const
{
	// Room for one more block first (the slot found must stay valid).
	if (overLoad(t.blocks_used + 1, t.mask + 1)) grow(t);
	BlockSlot& b = probe(t.blocks, t.mask, blockKeyOf(key));
	const uint64_t bit = voxelBitOf(key);
	if (b.key == kEmpty)
	{
		b.key = blockKeyOf(key);
		t.blocks_used++;
	}
	else if (b.taken & bit)
		return false;
	b.taken |= bit;
	return true;
}

const void* DenseMap::slotAddress(const Tile& t, uint64_t key) const
{
	if (t.spilled || t.blocks.empty()) return nullptr;
	return &t.blocks[slotOf(blockKeyOf(key), t.mask)];
}

void DenseMap::prefetch(const Eigen::Vector3f& xyz) const
{
	uint64_t key;
	if (moved_ || !xyz.allFinite() || !voxelKey(xyz, inv_voxel_, key)) return;
	if (const Tile* t = findTile(key))
		if (const void* slot = slotAddress(*t, key)) __builtin_prefetch(slot);
}

bool DenseMap::add(const DensePoint& p)
{
	DensePoint* q = claim(p.xyz);
	if (q) *q = p;
	return q != nullptr;
}

std::vector<DensePoint> DenseMap::points() const
{
	std::vector<DensePoint> all;
	all.reserve(size_);
	forEachTile([&](const std::vector<DensePoint>& pts)
	            { all.insert(all.end(), pts.begin(), pts.end()); });
	return all;
}

namespace
{
/** Moves the blocks of `table` into a table of `slots` slots. */
template <typename Slot>
void rehashTable(std::vector<Slot>& table, size_t& mask, size_t slots)
{
	std::vector<Slot> old(slots);
	old.swap(table);
	adviseHugePages(table);
	mask = table.size() - 1;
	for (const Slot& b : old)
		if (b.key != kEmpty) probe(table, mask, b.key) = b;
}
}  // namespace

void DenseMap::grow(Tile& t) const
{
	rehashTable(t.blocks, t.mask, 2 * (t.mask + 1));
}

size_t DenseMap::spillFar(const Eigen::Vector2d& centre, double radius_m,
                          const std::shared_ptr<core::SpillFile>& spill)
{
	if (tile_vox_ == 0 || !spill || moved_) return 0;
	if (spill_ && spill_ != spill)
		throw std::logic_error("DenseMap::spillFar: another spill file");
	spill_ = spill;
	const double edge = tile_vox_ * voxel_m_;
	size_t moved = 0;
	for (auto& tp : tiles_)
	{
		Tile& t = *tp;
		if (t.spilled || t.count == 0) continue;
		const double x0 = t.tx * edge, y0 = t.ty * edge;
		const double dx =
		    std::max({x0 - centre.x(), 0.0, centre.x() - (x0 + edge)});
		const double dy =
		    std::max({y0 - centre.y(), 0.0, centre.y() - (y0 + edge)});
		if (dx * dx + dy * dy <= radius_m * radius_m) continue;
		// Only the points kept since the last spill are written: the
		// earlier ones never left the disk.
		if (!t.points.empty())
			t.chunks.push_back(
			    {spill_->appendVector(t.points), t.points.size()});
		std::vector<DensePoint>().swap(t.points);
		std::vector<BlockSlot>().swap(t.blocks);
		t.mask = 0;
		t.spilled = true;
		moved++;
	}
	return moved;
}

void DenseMap::transformPoints(const std::function<void(DensePoint&)>& move)
{
	std::vector<DensePoint> buf;
	for (auto& tp : tiles_)
	{
		Tile& t = *tp;
		// In place in the spill file: memory one chunk, no more disk.
		for (const auto& c : t.chunks)
		{
			spill_->readVector(c.offset, c.count, buf);
			for (auto& p : buf) move(p);
			spill_->overwriteVector(c.offset, buf);
		}
		for (auto& p : t.points) move(p);
		// The voxel table no longer matches the points.
		std::vector<BlockSlot>().swap(t.blocks);
		t.mask = 0;
		t.blocks_used = 0;
	}
	moved_ = true;
	have_last_ = false;
}

void DenseMap::reload(Tile& t)
{
	// The table only: a revisit near the sensor costs its blocks (~1.5
	// bytes a point), not the points themselves (20 bytes) as well.
	size_t slots = kFirstSlots;
	while (overLoad(t.blocks_used + 1, slots)) slots *= 2;
	t.mask = slots - 1;
	t.blocks.assign(slots, BlockSlot{});
	adviseHugePages(t.blocks);
	t.blocks_used = 0;
	// The table is sized for every block already: no growth on the way.
	std::vector<DensePoint> buf;
	for (const auto& c : t.chunks)
	{
		spill_->readVector(c.offset, c.count, buf);
		for (const auto& p : buf)
		{
			uint64_t key = 0;
			voxelKey(p.xyz, inv_voxel_, key);
			insertKey(t, key);
		}
	}
	t.spilled = false;
}

void DenseMap::tilePoints(const Tile& t, std::vector<DensePoint>& out) const
{
	out.clear();
	out.reserve(t.count);
	std::vector<DensePoint> buf;
	for (const auto& c : t.chunks)
	{
		spill_->readVector(c.offset, c.count, buf);
		out.insert(out.end(), buf.begin(), buf.end());
	}
	out.insert(out.end(), t.points.begin(), t.points.end());
}

}  // namespace forest_slam::outputs
