#pragma once
// What `forest-slam map --out DIR` writes ([outputs]) and where the map frame
// sits on the Earth ([georeference]); every key in doc/outputs.md.
#include <mrpt/config/CLoadableOptions.h>

#include <string>

namespace forest_slam::outputs
{
struct OutputOptions : public mrpt::config::CLoadableOptions
{
	// Which files to write.
	bool trajectory_tum = true;
	bool trajectory_kitti = true;
	bool keyframes_simplemap = true;
	bool forest_map = true;
	bool las = true;
	bool ply = false;
	bool pcd = false;
	bool octomap_bt = true;
	bool octomap_ot = false;  ///< occupied voxels coloured by height
	bool trees_csv = true;
	bool trees_geojson = true;
	bool dtm_asc = true;
	bool report_html = true;

	// Keyframes (keyframes.simplemap, OctoMap ray casting): one every N scans
	// or every D metres of travel, whichever comes first.
	int keyframe_every_scans = 10;
	double keyframe_every_m = 1.0;
	double keyframe_voxel_m = 0.1;  ///< decimation of a keyframe's cloud
	double keyframe_max_range_m = 30.0;

	// Dense map (map.las/.ply/.pcd, DTM, trees when the tree layer is empty):
	// the first return falling into each voxel is kept with its attributes.
	double dense_voxel_m = 0.05;
	double dense_max_range_m = 40.0;

	// Memory bounded by area: dense-map tiles (dense_tile_m squares) farther
	// than dense_max_range_m + dense_tile_m from the sensor and every
	// keyframe cloud go to an unnamed scratch file in spill_dir (empty:
	// $TMPDIR, else /tmp), read back when needed; the outputs are the same.
	bool spill_to_disk = true;
	double dense_tile_m = 20.0;
	std::string spill_dir;

	// OctoMap: ray casting from each keyframe's sensor position.
	double octomap_resolution_m = 0.2;
	double octomap_max_range_m = 25.0;
	/** A keyframe within this distance of one already cast is skipped
	 * (stops, revisits: the 58-minute run's 11 laps cast every place 11
	 * times, 415-533 s). Less than keyframe_every_m, so the first pass
	 * keeps every keyframe (a view a metre on fills the gaps between the
	 * scan rings). 0: every keyframe. */
	double octomap_keyframe_spacing_m = 0.5;

	// Classification (ASPRS LAS 1.4 classes) by height above the terrain.
	double dtm_cell_m = 0.5;            ///< dtm.asc cell
	double ground_threshold_m = 0.15;   ///< |h| below this: ground (2)
	double low_vegetation_max_m = 0.5;  ///< below: low vegetation (3)
	double medium_vegetation_max_m =
	    2.0;                         ///< below: medium (4); above: high (5)
	int stem_class = 64;             ///< first user-definable class of LAS 1.4
	double stem_margin_m = 0.05;     ///< around the stem circle (DBH / 2)
	double stem_max_height_m = 4.0;  ///< stem class up to this height
	/** Run stem detection on the dense map when the tree layer is empty at
	 * the end of the run. */
	bool detect_trees_if_empty = true;

	/** Whether a file asked for reads the dense map: map.las/.ply/.pcd, the
	 * DTM, the report (its area), or trees detected on it. Without one, a
	 * run does not collect it (~11 % of an odometry-only run's CPU). */
	bool needsDenseMap() const
	{
		return las || ply || pcd || dtm_asc || report_html ||
		       (detect_trees_if_empty &&
		        (trees_csv || trees_geojson || forest_map));
	}
	/** Whether a file asked for reads the keyframe clouds. */
	bool needsKeyframeClouds() const
	{
		return keyframes_simplemap || octomap_bt || octomap_ot;
	}

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& section) const override;
};

/** [georeference]: optional. mode = none | enu_origin | utm.
 *  - enu_origin: the map frame is East-North-Up at (origin_lat_deg,
 *    origin_lon_deg, origin_alt_m); outputs go to that point's UTM zone.
 *  - utm: the map frame axes are the UTM grid axes of utm_zone/utm_north
 *    and projected = map + (utm_offset_e_m, utm_offset_n_m, utm_offset_h_m). */
struct GeoOptions : public mrpt::config::CLoadableOptions
{
	std::string mode = "none";
	double origin_lat_deg = 0, origin_lon_deg = 0, origin_alt_m = 0;
	int utm_zone = 0;
	bool utm_north = true;
	double utm_offset_e_m = 0, utm_offset_n_m = 0, utm_offset_h_m = 0;
	/** enu_origin: map -> ENU = Rz(yaw) * p + (x, y, z). Not INI keys: the
	 * back-end's GNSS estimate sets them (MappingPipeline::
	 * estimatedGeoreference); from the INI the map frame is the ENU frame. */
	double map_to_enu_yaw_rad = 0;
	double map_to_enu_x_m = 0, map_to_enu_y_m = 0, map_to_enu_z_m = 0;

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& section) const override;
	bool enabled() const { return mode != "none"; }
};

}  // namespace forest_slam::outputs
