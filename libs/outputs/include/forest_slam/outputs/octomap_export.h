#pragma once
// map.bt / map.ot: OctoMap occupancy from real ray casting of the keyframe
// clouds from their sensor positions (free space along every beam, occupied
// at its end), in the map frame.
#include <forest_slam/outputs/run_collector.h>

#include <string>

namespace forest_slam::outputs
{
struct OctomapSummary
{
	size_t keyframes = 0, rays = 0;
	size_t keyframes_skipped = 0;  ///< within keyframe_spacing_m of a cast one
	size_t occupied_leaves = 0, free_leaves = 0;
	double seconds = 0;
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
