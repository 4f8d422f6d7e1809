#pragma once
// The dense map behind map.las / map.ply / map.pcd: a voxel grid where the
// first return falling into each voxel is kept with its own attributes
// (position, time, intensity, scan angle), so the exported cloud is thinned
// to one point per voxel but every point is a real measurement.
#include <Eigen/Core>

#include <cstdint>
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
	explicit DenseMap(double voxel_m);

	/** Keeps the point if its voxel is still empty; returns true if kept. */
	bool add(const DensePoint& p);
	/** Claims the voxel of `xyz` for a point whose other attributes the
	 * caller fills in through the returned pointer (computed only for new
	 * voxels); nullptr if the voxel is taken or out of the grid. */
	DensePoint* claim(const Eigen::Vector3f& xyz);
	/** Hints the CPU to load the table slot of `xyz` (call a few dozen
	 * points ahead of claim: the table is far larger than the caches). */
	void prefetch(const Eigen::Vector3f& xyz) const;

	const std::vector<DensePoint>& points() const { return points_; }
	size_t size() const { return points_.size(); }
	double voxelSize() const { return voxel_m_; }
	/** Absolute time (UNIX seconds) of t_s = 0; set by the owner. */
	double timeOrigin() const { return t0_; }
	void setTimeOrigin(double t0) { t0_ = t0; }
	size_t memoryBytes() const;

   private:
	double voxel_m_, inv_voxel_;
	double t0_ = 0;
	std::vector<DensePoint> points_;
	// Open addressing (linear probing) on packed voxel keys: no allocation
	// per voxel; lookups miss the CPU cache, so callers prefetch() a batch
	// of points ahead of claiming them.
	std::vector<uint64_t> keys_;   ///< kEmpty or packed voxel key
	std::vector<uint32_t> index_;  ///< into points_, per slot
	size_t mask_ = 0;
	void grow();
};

}  // namespace forest_slam::outputs
