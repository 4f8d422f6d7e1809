#include <forest_slam/core/config.h>
#include <forest_slam/outputs/output_options.h>

#include <cmath>

namespace forest_slam::outputs
{
#define FS_OUTPUT_FIELDS(X)                                                  \
	X(trajectory_tum)                                                        \
	X(trajectory_kitti)                                                      \
	X(keyframes_simplemap)                                                   \
	X(forest_map)                                                            \
	X(las)                                                                   \
	X(ply)                                                                   \
	X(pcd)                                                                   \
	X(octomap_bt)                                                            \
	X(octomap_ot) X(trees_csv) X(trees_geojson) X(dtm_asc) X(report_html)    \
	    X(keyframe_every_scans) X(keyframe_every_m) X(keyframe_voxel_m)      \
	        X(keyframe_max_range_m) X(dense_voxel_m) X(dense_max_range_m)    \
	            X(octomap_resolution_m) X(octomap_max_range_m) X(dtm_cell_m) \
	                X(ground_threshold_m) X(low_vegetation_max_m)            \
	                    X(medium_vegetation_max_m) X(stem_class)             \
	                        X(stem_margin_m) X(stem_max_height_m)            \
	                            X(detect_trees_if_empty) X(spill_to_disk)    \
	                                X(dense_tile_m) X(spill_dir)             \
	                                    X(octomap_keyframe_spacing_m)

void OutputOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                       const std::string& s)
{
#define FS_OUTPUT_LOAD(f) FS_LOAD(c, s, f);
	FS_OUTPUT_FIELDS(FS_OUTPUT_LOAD)
#undef FS_OUTPUT_LOAD
	const auto bad = [&](const std::string& what) {
		throw core::ConfigError(core::configOrigin(c) + ": [" + s + "] " +
		                        what);
	};
	if (keyframe_every_scans < 1) bad("keyframe_every_scans must be >= 1");
	if (!(keyframe_every_m > 0)) bad("keyframe_every_m must be > 0");
	if (!(keyframe_voxel_m > 0)) bad("keyframe_voxel_m must be > 0");
	if (!(keyframe_max_range_m > 0)) bad("keyframe_max_range_m must be > 0");
	if (!(dense_voxel_m >= 0.005)) bad("dense_voxel_m must be >= 0.005 (5 mm)");
	if (!(dense_max_range_m > 0)) bad("dense_max_range_m must be > 0");
	if (!(dense_tile_m >= 1)) bad("dense_tile_m must be >= 1");
	if (!(octomap_resolution_m >= 0.01))
		bad("octomap_resolution_m must be >= 0.01");
	if (!(octomap_max_range_m > 0)) bad("octomap_max_range_m must be > 0");
	if (!(octomap_keyframe_spacing_m >= 0))
		bad("octomap_keyframe_spacing_m must be >= 0");
	if (!(dtm_cell_m > 0)) bad("dtm_cell_m must be > 0");
	if (!(ground_threshold_m > 0)) bad("ground_threshold_m must be > 0");
	if (!(low_vegetation_max_m > ground_threshold_m &&
	      medium_vegetation_max_m > low_vegetation_max_m))
		bad("need ground_threshold_m < low_vegetation_max_m < "
		    "medium_vegetation_max_m");
	if (stem_class < 0 || stem_class > 255)
		bad("stem_class must be a LAS class 0..255 (64..255 are user "
		    "definable)");
	if (!(stem_margin_m >= 0) || !(stem_max_height_m > 0))
		bad("need stem_margin_m >= 0 and stem_max_height_m > 0");
}

void OutputOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                     const std::string& s) const
{
#define FS_OUTPUT_SAVE(f) c.write(s, #f, f);
	FS_OUTPUT_FIELDS(FS_OUTPUT_SAVE)
#undef FS_OUTPUT_SAVE
}

void GeoOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                    const std::string& s)
{
	FS_LOAD(c, s, mode);
	FS_LOAD(c, s, origin_lat_deg);
	FS_LOAD(c, s, origin_lon_deg);
	FS_LOAD(c, s, origin_alt_m);
	FS_LOAD(c, s, utm_zone);
	FS_LOAD(c, s, utm_north);
	FS_LOAD(c, s, utm_offset_e_m);
	FS_LOAD(c, s, utm_offset_n_m);
	FS_LOAD(c, s, utm_offset_h_m);
	const std::string where = core::configOrigin(c) + ": [" + s + "] ";
	if (mode != "none" && mode != "enu_origin" && mode != "utm")
		throw core::ConfigError(
		    where + "mode: expected 'none', 'enu_origin' or 'utm', got '" +
		    mode + "'");
	if (mode == "enu_origin" &&
	    !(std::abs(origin_lat_deg) <= 84 && std::abs(origin_lon_deg) <= 180))
		throw core::ConfigError(
		    where +
		    "origin_lat_deg must be within +-84 (UTM) and origin_lon_deg "
		    "within +-180");
	if (mode == "utm" && !(utm_zone >= 1 && utm_zone <= 60))
		throw core::ConfigError(where + "utm_zone must be 1..60, got " +
		                        std::to_string(utm_zone));
}

void GeoOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                  const std::string& s) const
{
	c.write(s, "mode", mode);
	c.write(s, "origin_lat_deg", origin_lat_deg);
	c.write(s, "origin_lon_deg", origin_lon_deg);
	c.write(s, "origin_alt_m", origin_alt_m);
	c.write(s, "utm_zone", utm_zone);
	c.write(s, "utm_north", utm_north);
	c.write(s, "utm_offset_e_m", utm_offset_e_m);
	c.write(s, "utm_offset_n_m", utm_offset_n_m);
	c.write(s, "utm_offset_h_m", utm_offset_h_m);
}

}  // namespace forest_slam::outputs
