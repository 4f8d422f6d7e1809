#include <forest_slam/core/config.h>
#include <forest_slam/trees/tree_options.h>

#include <mrpt/config/CConfigFileBase.h>

#include <stdexcept>
#include <string>

namespace forest_slam::trees
{
#define FS_TREES_FIELDS(X)                                                     \
	X(dtm_cell_m)                                                              \
	X(dtm_window_cells)                                                        \
	X(dtm_max_step_m)                                                          \
	X(dtm_max_slope_deg)                                                       \
	X(slice_min_m)                                                             \
	X(slice_max_m)                                                             \
	X(slice_step_m)                                                            \
	X(slice_thickness_m)                                                       \
	X(kmeans_branching)                                                        \
	X(kmeans_leaf_points)                                                      \
	X(link_distance_m)                                                         \
	X(min_slice_points)                                                        \
	X(min_dbh_m)                                                               \
	X(max_dbh_m) X(section_max_rmse_m) X(section_rmse_rel) X(                  \
	    section_min_arc_deg) X(section_min_inlier_ratio) X(max_centre_step_m)  \
	    X(max_radius_ratio) X(max_slice_gap) X(min_slices) X(max_lean_deg) X(  \
	        max_taper_m_per_m) X(max_axis_rmse_m) X(min_tree_points)           \
	        X(dbh_height_m) X(dbh_band_half_m) X(sor_k) X(sor_omega) X(        \
	            min_dbh_points) X(ransac_iterations) X(ransac_inlier_m)        \
	            X(seed) X(arc_bin_deg) X(good_arc_deg) X(good_rmse_m) X(       \
	                top_search_radius_m) X(top_max_gap_m) X(layer_enabled)     \
	                X(layer_voxel_m) X(layer_ground_cell_m) X(                 \
	                    layer_min_hag_m) X(layer_max_hag_m)                    \
	                    X(layer_max_range_m) X(layer_complete_distance_m) X(   \
	                        layer_margin_m) X(slice_cell_m) X(dbh_along_rays)  \
	                        X(section_ring_search) X(layer_spill_to_disk) X(   \
	                            dbh_segment_scans) X(dbh_segment_shift_m)      \
	                            X(dbh_range_step_m) X(dbh_segment_band_half_m) \
	                                X(dbh_drift_sigma_m_per_s)                 \
	                                    X(layer_detect_during_run)             \
	                                        X(layer_redetect_growth)           \
	                                            X(dbh_silhouette_max_m)        \
	                                                X(layer_dump_dir)

void TreeOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                     const std::string& s)
{
#define FS_TREES_LOAD(f) FS_LOAD(c, s, f);
	FS_TREES_FIELDS(FS_TREES_LOAD)
#undef FS_TREES_LOAD
	auto bad = [&](const std::string& what) {
		throw core::ConfigError(core::configOrigin(c) + ": [" + s + "] " +
		                        what);
	};
	if (dtm_cell_m <= 0) bad("dtm_cell_m must be > 0");
	if (!(dtm_max_slope_deg >= 0 && dtm_max_slope_deg < 90))
		bad("dtm_max_slope_deg must be in [0, 90) (0: off)");
	if (slice_cell_m < 0) bad("slice_cell_m must be >= 0");
	if (slice_step_m <= 0 || slice_thickness_m <= 0 ||
	    slice_max_m <= slice_min_m)
		bad("slices need slice_step_m > 0, slice_thickness_m > 0, slice_max_m "
		    "> slice_min_m");
	if (kmeans_branching < 2) bad("kmeans_branching must be >= 2");
	if (kmeans_leaf_points < 2) bad("kmeans_leaf_points must be >= 2");
	if (min_dbh_m <= 0 || max_dbh_m <= min_dbh_m)
		bad("need 0 < min_dbh_m < max_dbh_m");
	if (sor_k < 1) bad("sor_k must be >= 1");
	if (min_slices < 1) bad("min_slices must be >= 1");
	if (dbh_band_half_m <= 0) bad("dbh_band_half_m must be > 0");
	if (layer_voxel_m <= 0 || layer_ground_cell_m <= 0 ||
	    layer_max_range_m <= 0 || layer_margin_m < 0 ||
	    layer_complete_distance_m < 0)
		bad("layer_voxel_m, layer_ground_cell_m, layer_max_range_m must be > "
		    "0, layer_margin_m and layer_complete_distance_m >= 0");
	if (dbh_segment_scans < 0) bad("dbh_segment_scans must be >= 0");
	if (dbh_segment_shift_m <= 0) bad("dbh_segment_shift_m must be > 0");
	if (dbh_range_step_m < 0) bad("dbh_range_step_m must be >= 0");
	if (dbh_segment_band_half_m <= 0)
		bad("dbh_segment_band_half_m must be > 0");
	if (dbh_drift_sigma_m_per_s < 0)
		bad("dbh_drift_sigma_m_per_s must be >= 0");
	if (dbh_silhouette_max_m < 0) bad("dbh_silhouette_max_m must be >= 0");
	if (layer_detect_during_run != "auto" &&
	    layer_detect_during_run != "true" && layer_detect_during_run != "false")
		bad("layer_detect_during_run must be auto, true or false, got '" +
		    layer_detect_during_run + "'");
	if (!(layer_redetect_growth >= 1))
		bad("layer_redetect_growth must be >= 1 (1: detect a column again "
		    "after every change), got " +
		    std::to_string(layer_redetect_growth));
	if (layer_max_hag_m <= layer_min_hag_m)
		bad("layer_max_hag_m must be > layer_min_hag_m");
}

void TreeOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                   const std::string& s) const
{
#define FS_TREES_SAVE(f) c.write(s, #f, f);
	FS_TREES_FIELDS(FS_TREES_SAVE)
#undef FS_TREES_SAVE
}

}  // namespace forest_slam::trees
