#include <forest_slam/core/config.h>
#include <forest_slam/loop/loop_options.h>

#include <mrpt/config/CConfigFileBase.h>

namespace forest_slam::loop
{
#define FS_LOOP_FIELDS(X)        \
	X(enabled)                   \
	X(keyframe_distance_m)       \
	X(keyframe_angle_deg)        \
	X(cloud_voxel_m)             \
	X(cloud_max_range_m)         \
	X(min_travel_m)              \
	X(search_radius_m)           \
	X(search_drift_fraction)     \
	X(max_candidates)            \
	X(detect_every_keyframes)    \
	X(closure_spacing_keyframes) \
	X(submap_keyframes)          \
	X(descriptor)                \
	X(descriptor_rings)          \
	X(descriptor_sectors)        \
	X(descriptor_radius_m)       \
	X(descriptor_keyframes)      \
	X(descriptor_retrieval)      \
	X(descriptor_max_distance)   \
	X(descriptor_distinct_ratio) \
	X(descriptor_candidates)     \
	X(icp_iterations)            \
	X(icp_max_points)            \
	X(icp_start_distance_m)      \
	X(icp_final_distance_m)      \
	X(min_overlap)               \
	X(max_rmse_m)                \
	X(min_information_ratio)     \
	X(consistency_chi2)          \
	X(verify_threads)            \
	X(odom_sigma_t_m)            \
	X(odom_sigma_t_per_m)        \
	X(odom_sigma_r_deg)          \
	X(odom_sigma_r_deg_per_m)    \
	X(loop_sigma_t_m)            \
	X(loop_sigma_r_deg)          \
	X(latency_keyframes)         \
	X(gnss_enabled)              \
	X(gnss_min_quality)          \
	X(gnss_max_sigma_m)          \
	X(gnss_gate_sigma)           \
	X(gnss_min_baseline_m)       \
	X(gnss_correlation_s)        \
	X(level_with_imu)            \
	X(inject_yaw_deg_per_m)      \
	X(inject_z_m_per_m)          \
	X(inject_every_m)

void LoopOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                     const std::string& s)
{
#define FS_LOOP_LOAD(f) FS_LOAD(c, s, f);
	FS_LOOP_FIELDS(FS_LOOP_LOAD)
#undef FS_LOOP_LOAD
	const std::string where = core::configOrigin(c) + ": [" + s + "] ";
	auto positive = [&](double v, const char* key)
	{
		if (!(v > 0))
			throw core::ConfigError(where + key + " must be > 0, got " +
			                        std::to_string(v));
	};
	positive(keyframe_distance_m, "keyframe_distance_m");
	positive(keyframe_angle_deg, "keyframe_angle_deg");
	positive(cloud_voxel_m, "cloud_voxel_m");
	positive(cloud_max_range_m, "cloud_max_range_m");
	positive(search_radius_m, "search_radius_m");
	positive(icp_start_distance_m, "icp_start_distance_m");
	positive(icp_final_distance_m, "icp_final_distance_m");
	positive(max_rmse_m, "max_rmse_m");
	positive(consistency_chi2, "consistency_chi2");
	positive(odom_sigma_t_m, "odom_sigma_t_m");
	positive(odom_sigma_r_deg, "odom_sigma_r_deg");
	positive(loop_sigma_t_m, "loop_sigma_t_m");
	positive(loop_sigma_r_deg, "loop_sigma_r_deg");
	positive(gnss_max_sigma_m, "gnss_max_sigma_m");
	positive(gnss_gate_sigma, "gnss_gate_sigma");
	positive(inject_every_m, "inject_every_m");
	if (!(min_travel_m >= 0) || !(search_drift_fraction >= 0) ||
	    !(odom_sigma_t_per_m >= 0) || !(odom_sigma_r_deg_per_m >= 0) ||
	    !(gnss_min_baseline_m >= 0) || !(gnss_correlation_s >= 0))
		throw core::ConfigError(
		    where +
		    "min_travel_m, search_drift_fraction, odom_sigma_*_per_m and "
		    "gnss_min_baseline_m, gnss_correlation_s must be >= 0");
	if (!(min_overlap > 0 && min_overlap <= 1) ||
	    !(min_information_ratio >= 0 && min_information_ratio < 1))
		throw core::ConfigError(where +
		                        "min_overlap must be in (0, 1], "
		                        "min_information_ratio in [0, 1)");
	if (max_candidates < 1 || detect_every_keyframes < 1 ||
	    closure_spacing_keyframes < 0 || submap_keyframes < 0 ||
	    icp_iterations < 1 || latency_keyframes < 0 || gnss_min_quality < 1)
		throw core::ConfigError(
		    where +
		    "max_candidates, detect_every_keyframes, icp_iterations and "
		    "gnss_min_quality must be >= 1; closure_spacing_keyframes, "
		    "submap_keyframes and latency_keyframes >= 0");
	if (verify_threads < 1 || verify_threads > 64)
		throw core::ConfigError(where +
		                        "verify_threads must be in [1, 64], got " +
		                        std::to_string(verify_threads));
	if (icp_max_points != 0 && icp_max_points < 200)
		throw core::ConfigError(where +
		                        "icp_max_points must be 0 (all) or >= 200");
	if (descriptor_rings < 2 || descriptor_sectors < 8 ||
	    descriptor_keyframes < 0 || descriptor_retrieval < 1 ||
	    descriptor_candidates < 1)
		throw core::ConfigError(
		    where +
		    "descriptor_rings must be >= 2, descriptor_sectors >= 8, "
		    "descriptor_retrieval and descriptor_candidates >= 1, "
		    "descriptor_keyframes >= 0");
	positive(descriptor_radius_m, "descriptor_radius_m");
	if (!(descriptor_max_distance > 0 && descriptor_max_distance < 1) ||
	    !(descriptor_distinct_ratio > 0 && descriptor_distinct_ratio <= 1))
		throw core::ConfigError(where +
		                        "descriptor_max_distance must be in (0, 1), "
		                        "descriptor_distinct_ratio in (0, 1]");
	if (icp_final_distance_m > icp_start_distance_m)
		throw core::ConfigError(
		    where + "icp_final_distance_m must be <= icp_start_distance_m");
}

void LoopOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                   const std::string& s) const
{
#define FS_LOOP_SAVE(f) c.write(s, #f, f);
	FS_LOOP_FIELDS(FS_LOOP_SAVE)
#undef FS_LOOP_SAVE
}

}  // namespace forest_slam::loop
