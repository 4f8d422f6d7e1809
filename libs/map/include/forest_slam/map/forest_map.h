#pragma once
// CForestMap: the map of the paper's §4.5 as an MRPT metric map.
//  - a grid of cubic submaps (20 m by default), keyed by integer cell
//    coordinates, each with an edge cloud and a planar cloud kept by their own
//    voxel filters;
//  - a tree layer (stems with position, DBH, height, quality).
// Registered with MRPT's map factory as "forestMap" so CMultiMetricMap can
// create it from an INI "[map]" section, and serializable into MRPT archives.
#include <forest_slam/map/voxel_cloud.h>
#include <mrpt/config/CLoadableOptions.h>
#include <mrpt/maps/CMetricMap.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/math/TBoundingBox.h>
#include <mrpt/poses/CPose3D.h>

#include <Eigen/Geometry>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

namespace forest_slam::map
{
/** One stem of the tree layer. Coordinates in the map frame. */
struct TreeRecord
{
	uint32_t id = 0;
	double x = 0, y = 0;  ///< stem centre at breast height [m]
	double z_ground = 0;  ///< terrain elevation under the stem [m]
	double dbh_m = 0;
	double height_m = 0;  ///< 0 if the top was not seen
	uint32_t n_points = 0;
	double fit_rmse_m = 0;
	double arc_coverage_deg = 0;
	uint16_t n_slices = 0;
	uint8_t quality = 0;  ///< 0 = good; bit flags defined by libs/trees
	/** Horizontal distance from the stem to the run's trajectory [m]; NaN
	 * where there is none (a standalone cloud). Set when the outputs are
	 * written (outputs::setPathDistances), not stored in forest.map. */
	double path_distance_m = std::numeric_limits<double>::quiet_NaN();
};

/** A 20 m cubic cell of the map. */
struct Submap
{
	VoxelCloud edge, planar;
	size_t size() const { return edge.size() + planar.size(); }
};

using SubmapKey = VoxelKey;

/** Options of CForestMap (INI section [forest_map] in the mapping configs). */
struct ForestMapOptions : public mrpt::config::CLoadableOptions
{
	double submap_size_m = 20.0;  ///< edge of the cubic submaps
	double edge_voxel_m = 0.2;    ///< voxel filter of edge points
	double planar_voxel_m = 0.4;  ///< voxel filter of planar points
	/** Insertion of a raw rotating scan: LOAM smoothness threshold above
	 * which a point is an edge (below: planar). */
	double edge_smoothness_threshold = 0.1;
	int smoothness_half_window = 5;  ///< points each side, same ring
	double max_insert_range_m = 80.0;
	double likelihood_sigma_m = 0.2;  ///< for computeObservationLikelihood
	int likelihood_decimation = 10;

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& section) const override;
	/** Throws std::invalid_argument naming the bad field. */
	void validate() const;
};

class CForestMap : public mrpt::maps::CMetricMap
{
	DEFINE_SERIALIZABLE(CForestMap, forest_slam::map)

   public:
	using TOptions = ForestMapOptions;

	explicit CForestMap(const TOptions& opts = TOptions());

	/** Changes the options; clears the map if voxel or submap sizes change. */
	void setOptions(const TOptions& opts);
	const TOptions& options() const { return opts_; }

	/** Inserts already-classified feature points given in the map frame. */
	void insertFeatures(const std::vector<Eigen::Vector3f>& edge_map,
	                    const std::vector<Eigen::Vector3f>& planar_map);
	/** Same, with points in the sensor frame and the sensor pose in the map. */
	void insertFeatures(const std::vector<Eigen::Vector3f>& edge_sensor,
	                    const std::vector<Eigen::Vector3f>& planar_sensor,
	                    const Eigen::Isometry3d& sensor_to_map);

	/** Edge and planar centroids of all submaps whose cube intersects the
	 * sphere (centre, radius): the local map for scan-to-map matching. */
	void collectNear(const Eigen::Vector3d& centre, double radius_m,
	                 std::vector<Eigen::Vector3f>& edge,
	                 std::vector<Eigen::Vector3f>& planar) const;
	/** Keys of the submaps intersecting that sphere. */
	std::vector<SubmapKey> submapsNear(const Eigen::Vector3d& centre,
	                                   double radius_m) const;
	SubmapKey submapKeyOf(const Eigen::Vector3f& p) const;

	using SubmapTable = std::unordered_map<SubmapKey, Submap, VoxelKeyHash>;
	/** The submaps of the current segment (all of them unless
	 * startSegment was called since the last transformSegments). */
	const SubmapTable& submaps() const { return submaps_; }

	/** Loop corrections. Starts a new segment: the voxels of the points
	 * inserted from now on are kept apart from the earlier ones (the
	 * back-end moved the frame the points arrive in; averaged together,
	 * the two would smear the map) until transformSegments merges them.
	 * Point and memory counts include every segment; collectNear,
	 * submapsNear, likelihood and the point views see the current one. */
	void startSegment();
	size_t segmentCount() const { return frozen_.size() + 1; }
	/** Moves every voxel rigidly: its centroid c (segment s, 0 = oldest)
	 * goes to T(s, c) * c, its sum and count kept, and merges the
	 * segments into one map again (voxels landing in one voxel add up).
	 * Submap by submap: memory about one map. */
	void transformSegments(
	    const std::function<Eigen::Isometry3f(size_t, const Eigen::Vector3f&)>&
	        T);
	size_t edgePointCount() const;
	size_t planarPointCount() const;
	/** Heap bytes of the submaps (estimate, core/memory.h). */
	size_t memoryBytes() const;

	/** The tree layer. */
	const std::vector<TreeRecord>& trees() const { return trees_; }
	void setTrees(std::vector<TreeRecord> trees) { trees_ = std::move(trees); }

	mrpt::math::TBoundingBoxf boundingBox() const;

	// CMetricMap interface
	bool isEmpty() const override;
	void saveMetricMapRepresentationToFile(
	    const std::string& filNamePrefix) const override;
	const mrpt::maps::CSimplePointsMap* getAsSimplePointsMap() const override;
	void getVisualizationInto(mrpt::opengl::CSetOfObjects& o) const override;
	std::string asString() const override;

	MAP_DEFINITION_START(CForestMap)
	TOptions forestOpts;
	MAP_DEFINITION_END(CForestMap)

   protected:
	void internal_clear() override;
	bool internal_insertObservation(
	    const mrpt::obs::CObservation& obs,
	    const std::optional<const mrpt::poses::CPose3D>& robotPose =
	        std::nullopt) override;
	double internal_computeObservationLikelihood(
	    const mrpt::obs::CObservation& obs,
	    const mrpt::poses::CPose3D& takenFrom) const override;
	bool internal_canComputeObservationLikelihood(
	    const mrpt::obs::CObservation& obs) const override;

   private:
	TOptions opts_;
	SubmapTable submaps_;
	/** A segment no point is inserted into any more: its voxels (sum and
	 * count) in one array, 16 bytes each against ~50 in the submaps'
	 * tables. Only transformSegments reads them back, and it re-buckets
	 * every voxel anyway. In table order: per submap, its edge voxels then
	 * its planar ones (`counts`). */
	struct FrozenSegment
	{
		std::vector<VoxelCloud::Accum> voxels;
		std::vector<std::pair<uint32_t, uint32_t>> counts;  ///< edge, planar
		size_t edge = 0, planar = 0;                        ///< totals
	};
	std::vector<FrozenSegment> frozen_;  ///< earlier segments, oldest first
	std::vector<TreeRecord> trees_;
	mutable std::shared_ptr<mrpt::maps::CSimplePointsMap> cached_points_;

	Submap& submapFor(const Eigen::Vector3f& p)
	{
		return submapIn(submaps_, p);
	}
	Submap& submapIn(SubmapTable& table, const Eigen::Vector3f& p) const;
	/** Moves `pts` by T into the edge or planar clouds of their submaps. */
	void insertPoints(const std::vector<Eigen::Vector3f>& pts, bool edges,
	                  const Eigen::Isometry3f& T);
	void markDirty() { cached_points_.reset(); }
};

/** Makes sure CForestMap is known to MRPT's class registry and map factory
 * (needed before reading it from an archive or creating it through
 * CMultiMetricMap when linking statically). Idempotent. */
void registerForestMapClasses();

/** LOAM smoothness (curvature) of each point of one ring-ordered scan line
 * over `half_window` neighbours each side: flag[i] = 1 if point i is an edge
 * (smoothness > edge_threshold), 0 if planar. Points in the sensor frame,
 * ordered by firing; the first/last `half_window` points are planar. */
std::vector<uint8_t> smoothnessEdgeFlags(
    const std::vector<Eigen::Vector3f>& ring_points, int half_window,
    double edge_threshold);

}  // namespace forest_slam::map
