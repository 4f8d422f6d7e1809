#pragma once
// map.bt / map.ot: OctoMap occupancy from real ray casting of the keyframe
// clouds from their sensor positions (free space along every beam, occupied
// at its end), in the map frame.
#include <forest_slam/outputs/run_collector.h>

#include <octomap/OcTreeKey.h>
#include <octomap/Pointcloud.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace forest_slam::outputs
{
struct OctomapSummary
{
	size_t keyframes = 0, rays = 0;
	size_t keyframes_skipped = 0;  ///< within keyframe_spacing_m of a cast one
	size_t occupied_leaves = 0, free_leaves = 0;
	double seconds = 0;
};

/** The voxels one cloud's rays cross (free) and end in (occupied), exactly
 * as octomap's OccupancyOcTreeBase::computeDiscreteUpdate finds them (end
 * points merged per voxel, rays cast to the voxel centres, beams longer than
 * max_range_m free up to it only, a voxel both free and occupied is
 * occupied), each list in tree order (Morton order of the keys, most
 * significant bit first). octomap collects them in std::unordered_sets, a
 * heap node per key: most of the export's time went there. Reusable: keeps
 * its tables between clouds. */
class DiscreteRayCaster
{
   public:
	explicit DiscreteRayCaster(double resolution_m);
	~DiscreteRayCaster();
	void cast(const octomap::Pointcloud& cloud, const octomap::point3d& origin,
	          double max_range_m, std::vector<octomap::OcTreeKey>& free,
	          std::vector<octomap::OcTreeKey>& occupied);
	/** The same sets as the keys' Morton codes (most significant bit
	 * first: x, y, z of the tree's top level), sorted. */
	void castCodes(const octomap::Pointcloud& cloud,
	               const octomap::point3d& origin, double max_range_m,
	               std::vector<uint64_t>& free,
	               std::vector<uint64_t>& occupied);

   private:
	struct Impl;
	std::unique_ptr<Impl> impl_;
};

/** Casts every keyframe point (up to max_range_m; farther beams mark free
 * space up to max_range_m only) into an octomap::OcTree of resolution_m and
 * writes it with writeBinary to `bt_path` (atomic). If `ot_path` is not
 * empty, also a ColorOcTree of the occupied voxels coloured by height
 * (AbstractOcTree::write, .ot). A keyframe whose sensor is within
 * `keyframe_spacing_m` of one already cast is skipped (0: none is). */
OctomapSummary writeOctomap(const Keyframes& keyframes, double resolution_m,
                            double max_range_m, const std::string& bt_path,
                            const std::string& ot_path = "",
                            double keyframe_spacing_m = 0);
/** Same, the clouds read one at a time through `cloud_of(i)` (e.g.
 * RunCollector::keyframeCloud: they may be on disk). */
OctomapSummary writeOctomap(const Keyframes& keyframes,
                            const KeyframeCloudLoader& cloud_of,
                            double resolution_m, double max_range_m,
                            const std::string& bt_path,
                            const std::string& ot_path = "",
                            double keyframe_spacing_m = 0);

}  // namespace forest_slam::outputs
