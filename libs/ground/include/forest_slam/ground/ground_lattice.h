#pragma once
// Ground labelling on a 2D lattice (paper §4.1, after Rummelhard et al.):
// each lattice node holds the terrain elevation h and two slopes (sx, sy)
// with a variance; every point is assigned to its nearest node and labelled
// ground / not ground by its height above the node's local plane. Node
// estimates persist between scans (keyed by their global grid index in the
// gravity-aligned map frame, so the motion estimate moves the prior with the
// sensor) and serve as a prior where the current scan sees little ground.
// The lattice doubles as a local terrain model (DTM).
#include <mrpt/config/CLoadableOptions.h>

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

namespace forest_slam::ground
{
struct GroundOptions : public mrpt::config::CLoadableOptions
{
	double node_spacing_m = 1.0;  ///< lattice resolution
	double radius_m = 40.0;  ///< points farther from the sensor are not used
	/** A point is ground if within this distance of its node's plane. */
	double ground_threshold_m = 0.15;
	/** Along a beam the ground band (ground_threshold_m thick) is at most
	 * this long: at grazing incidence the threshold shrinks to
	 * max_band_length_m * tan(incidence), the incidence taken as
	 * atan(sensor height above the ground under it / horizontal distance).
	 * A grazing beam crosses low foliage over metres inside a full band,
	 * while its ground returns lie on the node plane (one ring measured it)
	 * [m] (0: off). */
	double max_band_length_m = 0.0;
	/** Candidate ground points of a node: within this band above its
	 * lowest point (ground under grass/litter is not a perfect plane). */
	double lowest_band_m = 0.25;
	double max_slope_deg = 35.0;  ///< steeper local planes are rejected
	/** A node's level may exceed what a plane through the levels of the
	 * nodes around it predicts by at most this much: rejects shrub tops and
	 * stem bases taken for ground where the true ground is hidden. */
	double max_step_m = 0.2;
	/** An accepted level more than this above the plane of the ground
	 * around it is measured at that plane + max_rise_m: where the ground is
	 * hidden under low foliage the lowest returns are the foliage's [m]. */
	double max_rise_m = 0.05;
	/** Accepted ground within this distance of a node supports it (the
	 * plane its level must agree with) [m]. */
	double support_radius_m = 3.0;
	/** A node with no supporting ground around it may start the ground only
	 * within this distance of the sensor [m] ... */
	double seed_radius_m = 12.0;
	/** ... and at least this far below the sensor [m]. */
	double seed_below_sensor_m = 0.3;
	/** A point below the ground threshold is still not ground if another
	 * return lies foot_gap_m..foot_reach_m above it within about
	 * foot_radius_m horizontally: it is the foot of a stem, wall or shrub
	 * (0 turns the check off) [m]. */
	double foot_radius_m = 0.1;
	double foot_gap_m = 0.25;
	double foot_reach_m = 1.5;
	int min_points_per_node = 3;
	/** Per-scan growth of a node's prior variance [m^2] (terrain does not
	 * change, but drift and mislabels must be forgettable). */
	double prior_variance_growth_m2 = 0.0025;
	double measurement_variance_floor_m2 = 0.0004;

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& section) const override;
};

struct LatticeNode
{
	double h = 0, sx = 0, sy = 0;  ///< elevation [m] and slopes dz/dx, dz/dy
	double var_h = 1e6;            ///< variance of h [m^2]; large = unknown
	uint32_t observations = 0;     ///< scans that measured it
};

struct NodeKey
{
	int32_t i = 0, j = 0;
	bool operator==(const NodeKey& o) const { return i == o.i && j == o.j; }
};

/** The lattice nodes, in tiles of kTile x kTile created where the sensor
 * went: a scan reaches its nodes through a few tile look-ups instead of one
 * hash look-up per node. */
class NodeStore
{
   public:
	static constexpr int kTileBits = 5, kTile = 1 << kTileBits;
	using Tile = std::vector<LatticeNode>;  ///< kTile * kTile, row-major

	/** The node, or nullptr if its tile was never created. */
	const LatticeNode* find(const NodeKey& k) const;
	LatticeNode* find(const NodeKey& k);
	/** The tile holding node k (created if missing), and k's slot in it. */
	Tile& tile(const NodeKey& k, size_t& slot);
	LatticeNode& at(const NodeKey& k)
	{
		size_t slot;
		return tile(k, slot)[slot];
	}
	/** Heap bytes held (tiles and the table over them). */
	size_t memoryBytes() const
	{
		return tiles_.bucket_count() * sizeof(void*) +
		       tiles_.size() *
		           (2 * sizeof(void*) + sizeof(uint64_t) + sizeof(Tile) +
		            sizeof(LatticeNode) * kTile * kTile);
	}
	/** True until a node has been measured. */
	bool empty() const { return !measured_; }
	void markMeasured() { measured_ = true; }
	void clear()
	{
		tiles_.clear();
		measured_ = false;
	}

   private:
	static uint64_t tileKey(const NodeKey& k)
	{
		return (static_cast<uint64_t>(static_cast<uint32_t>(k.i >> kTileBits))
		        << 32) |
		       static_cast<uint32_t>(k.j >> kTileBits);
	}
	std::unordered_map<uint64_t, Tile> tiles_;
	bool measured_ = false;
};

class GroundLattice
{
   public:
	explicit GroundLattice(const GroundOptions& opts = GroundOptions());
	~GroundLattice();
	GroundLattice(const GroundLattice& o);
	GroundLattice& operator=(const GroundLattice& o);

	/** A node whose elevation variance is below this [m^2] is a confident
	 * prior: it supports its neighbours and vetoes levels far above it. */
	static constexpr double kConfidentVariance = 0.05;

	/** Labels the points (gravity-aligned frame, e.g. the map frame) of one
	 * scan seen from `sensor_xyz`: returns 1 for ground, 0 otherwise, and
	 * updates the lattice. NaN points are labelled 0. */
	std::vector<uint8_t> labelScan(const std::vector<Eigen::Vector3f>& pts,
	                               const Eigen::Vector3d& sensor_xyz);

	/** Terrain elevation at (x, y) by bilinear interpolation of the known
	 * nodes around it; false if none is known. */
	bool heightAt(double x, double y, double& z) const;

	const NodeStore& nodes() const { return nodes_; }
	const GroundOptions& options() const { return opts_; }
	NodeKey keyOf(double x, double y) const;
	void clear() { nodes_.clear(); }

   private:
	GroundOptions opts_;
	NodeStore nodes_;
	int half_ = 0;  ///< window half width [nodes] around the sensor's node
	std::vector<NodeKey> order_;  ///< window offsets, nearest first
	struct Scratch;               ///< per-scan buffers, reused
	std::unique_ptr<Scratch> scratch_;
};

}  // namespace forest_slam::ground
