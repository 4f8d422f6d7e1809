#pragma once
// The dense map behind map.las / map.ply / map.pcd: a voxel grid where the
// first return falling into each voxel is kept with its own attributes
// (position, time, intensity, scan angle), so the exported cloud is thinned
// to one point per voxel but every point is a real measurement.
//
// Memory is bounded by the area near the sensor, not by the area mapped:
// the grid is split into square tiles (columns of tile_m × tile_m); tiles
// farther from the sensor than any return can reach are moved to a spill
// file (spillFar). When a point falls into a spilled tile again, only its
// voxel table is rebuilt (4 bytes a slot): its points stay on disk and the
// new ones are kept in memory until the tile is spilled again, as one more
// chunk after the others. The kept points, and their order, are the same
// as with everything in memory.
#include <forest_slam/core/spill_file.h>

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <memory>
#include <unordered_map>
#include <vector>

namespace forest_slam::outputs
{
struct DensePoint
{
	Eigen::Vector3f xyz;     ///< map frame [m]
	float t_s = 0;           ///< seconds after DenseMap::timeOrigin()
	uint16_t intensity = 0;  ///< LAS convention: 16 bit (sensor 0..255 * 256)
	int16_t scan_angle = 0;  ///< LAS 1.4 units of 0.006 deg (beam elevation)
};

class DenseMap
{
   public:
	/** tile_m <= 0: one tile (no spilling). Tiles are whole voxels wide. */
	explicit DenseMap(double voxel_m, double tile_m = 0);
	DenseMap(DenseMap&&) = default;
	DenseMap& operator=(DenseMap&&) = default;

	/** Keeps the point if its voxel is still empty; returns true if kept. */
	bool add(const DensePoint& p);
	/** Claims the voxel of `xyz` for a point whose other attributes the
	 * caller fills in through the returned pointer (computed only for new
	 * voxels; valid until the next claim); nullptr if the voxel is taken or
	 * out of the grid. A spilled tile is read back first. */
	DensePoint* claim(const Eigen::Vector3f& xyz);
	/** Hints the CPU to load the table slot of `xyz` (call a few dozen
	 * points ahead of claim: the table is far larger than the caches). */
	void prefetch(const Eigen::Vector3f& xyz) const;

	/** Moves the tiles whose square lies farther than radius_m
	 * (horizontally) from `centre` to `spill` (the same file every call).
	 * Returns the number of tiles moved. */
	size_t spillFar(const Eigen::Vector2d& centre, double radius_m,
	                const std::shared_ptr<core::SpillFile>& spill);

	/** Moves every point with `move` (a loop correction: the pose of the
	 * point's scan changed), in place: the same points, each moved, in
	 * the same tiles and order (spilled tiles are read, moved and written
	 * back one at a time: memory one tile). Not voxelized again: a shift
	 * of a fraction of a voxel would put a fifth of the neighbours of a
	 * dense surface into one voxel and drop them (handheld run: 24.6 M ->
	 * 19.2 M points). The map is final afterwards: claim/add throw. */
	void transformPoints(const std::function<void(DensePoint&)>& move);

	/** f(const std::vector<DensePoint>&) once per tile with points, in the
	 * order the tiles were created, points in the order they were kept;
	 * spilled tiles are read back one at a time (memory: one tile). */
	template <class F>
	void forEachTile(F&& f) const
	{
		std::vector<DensePoint> buf;
		for (const auto& t : tiles_)
		{
			if (t->chunks.empty())
			{
				if (!t->points.empty())
					f(static_cast<const std::vector<DensePoint>&>(t->points));
				continue;
			}
			tilePoints(*t, buf);
			f(static_cast<const std::vector<DensePoint>&>(buf));
		}
	}
	/** Every point in one vector (forEachTile order): tests, small maps. */
	std::vector<DensePoint> points() const;

	size_t size() const { return size_; }
	double voxelSize() const { return voxel_m_; }
	/** Absolute time (UNIX seconds) of t_s = 0; set by the owner. */
	double timeOrigin() const { return t0_; }
	void setTimeOrigin(double t0) { t0_ = t0; }
	/** Heap bytes of the tiles in memory. */
	size_t memoryBytes() const;
	/** Bytes of the points in spilled tiles. */
	size_t spilledBytes() const;
	size_t tiles() const { return tiles_.size(); }
	/** Points held in memory (the others are in the spill file). */
	size_t pointsInMemory() const;
	size_t tilesSpilled() const;

   private:
	struct BlockSlot
	{
		uint64_t key = ~uint64_t(0);  ///< packed block key; all ones: empty
		uint64_t taken = 0;           ///< bit (i%4)*16 + (j%4)*4 + k%4
	};
	/** Points of a tile written to the spill file (in keeping order). */
	struct Chunk
	{
		uint64_t offset = 0;
		size_t count = 0;
	};
	struct Tile
	{
		int64_t tx = 0, ty = 0;     ///< tile index (voxel index / tile_vox_)
		std::vector<Chunk> chunks;  ///< on disk: the tile's first points
		std::vector<DensePoint> points;  ///< in memory: the points after
		size_t count = 0;                ///< chunks + points
		// Open addressing (linear probing) on blocks of 4 x 4 x 4 voxels:
		// a slot holds a block's key and one bit per voxel ("taken"; a
		// taken voxel's point is never looked up). The table is far larger
		// than the CPU caches and the claims are bound by its misses: a
		// block of 5 cm voxels holds ~15 kept points on the forest-sim
		// runs, so a scan's neighbouring returns share a slot (one cache
		// line) and a slot costs ~1.5 bytes a point instead of 5-11 for a
		// table of 4-byte voxel keys. Callers prefetch() a batch of points
		// ahead of claiming them.
		std::vector<BlockSlot> blocks;
		size_t mask = 0;
		size_t blocks_used = 0;  ///< kept while spilled: sizes the reload
		bool spilled = false;    ///< no voxel table: every point on disk
	};
	double voxel_m_, inv_voxel_;
	int64_t tile_vox_;  ///< voxels per tile edge; 0: one tile
	double t0_ = 0;
	size_t size_ = 0;
	std::vector<std::unique_ptr<Tile>> tiles_;       ///< creation order
	std::unordered_map<uint64_t, uint32_t> by_key_;  ///< tile key -> index
	mutable uint64_t last_key_ = 0;  ///< tile of the last lookup (cache)
	mutable uint32_t last_tile_ = 0;
	mutable bool have_last_ = false;
	bool moved_ = false;  ///< transformPoints ran: voxel tables dropped
	std::shared_ptr<core::SpillFile> spill_;

	uint64_t tileKeyOf(uint64_t voxel_key) const;
	/** Tile of a voxel key, nullptr if none. */
	Tile* findTile(uint64_t voxel_key) const;
	Tile& tileFor(uint64_t voxel_key);
	void grow(Tile& t) const;
	/** Marks the voxel taken; false if it was taken already. */
	bool insertKey(Tile& t, uint64_t key) const;
	/** The slot to prefetch for `key`, nullptr if t has no table. */
	const void* slotAddress(const Tile& t, uint64_t key) const;
	/** Rebuilds the voxel table of a spilled tile from its chunks. */
	void reload(Tile& t);
	/** Every point of a tile, chunks then memory, into `out`. */
	void tilePoints(const Tile& t, std::vector<DensePoint>& out) const;

	DensePoint* claimIn(Tile& t, uint64_t key, const Eigen::Vector3f& xyz);
};

}  // namespace forest_slam::outputs
