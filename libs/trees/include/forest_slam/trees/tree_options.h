#pragma once
// Every parameter of the tree layer (INI section [trees]); see doc/trees.md.
#include <mrpt/config/CLoadableOptions.h>

#include <string>

#include <cstdint>

namespace forest_slam::trees
{
struct TreeOptions : public mrpt::config::CLoadableOptions
{
	// Terrain model of a standalone cloud (the SLAM pipeline supplies its own).
	double dtm_cell_m = 1.0;   ///< grid cell of the lowest-point DTM
	int dtm_window_cells = 2;  ///< median window half-size for the filter
	double dtm_max_step_m =
	    0.3;  ///< a cell this far above its neighbourhood is not ground
	/** Ground rises at most this steeply from any lower cell: a cell above
	 * that bound (plus dtm_max_step_m) is not ground, before the median
	 * test (0: off). */
	double dtm_max_slope_deg = 45;

	// Stacked slices above local ground (issue 7: stems confirmed by slices).
	double slice_min_m = 0.5;
	double slice_max_m = 3.0;
	double slice_step_m = 0.25;
	double slice_thickness_m = 0.2;
	double slice_cell_m = 0;  ///< slices thinned to one point per cell (0: off)

	// Clustering of a slice: hierarchical k-means + neighbourhood merge (§4.2).
	int kmeans_branching = 4;  ///< k of each k-means level
	int kmeans_leaf_points =
	    75;  ///< σ: stop splitting at this size (paper: 50–100)
	double link_distance_m =
	    0.08;  ///< leaves with points this close are one object
	int min_slice_points = 12;  ///< smaller slice clusters are ignored

	// A slice cluster is a stem section if its circle is plausible.
	double min_dbh_m = 0.06;
	double max_dbh_m = 1.2;
	double section_max_rmse_m = 0.035;  ///< plus section_rmse_rel * radius
	double section_rmse_rel = 0.08;
	double section_min_arc_deg = 60;
	double section_min_inlier_ratio = 0.6;
	/** A cluster failing as a section is searched for a hollow ring inside
	 * it (stems joined with clutter: low spruce branches, shrubs). */
	bool section_ring_search = true;

	// Linking sections into stems: consistent centres, taper and lean.
	double max_centre_step_m = 0.10;  ///< per metre of height, on top of lean
	double max_radius_ratio = 1.4;    ///< between linked sections
	int max_slice_gap = 2;            ///< missing slices allowed inside a stem
	int min_slices = 4;               ///< slices confirming a stem
	double max_lean_deg = 35;
	double max_taper_m_per_m = 0.06;  ///< |d radius / d height|
	double max_axis_rmse_m = 0.05;  ///< section centres around the fitted axis
	int min_tree_points = 100;      ///< paper §4.2: ≥ 100 points per tree

	// DBH (§4.2): band above local ground, SOR, robust circle fit.
	double dbh_height_m = 1.3;
	double dbh_band_half_m = 0.3;  ///< 1.0–1.6 m (paper: 0.1)
	int sor_k = 10;
	double sor_omega = 0.4;
	int min_dbh_points = 15;
	/** Refine the DBH circle with range noise along the viewing rays where
	 * they are known (the tree layer of a SLAM run). */
	bool dbh_along_rays = true;
	/** Tree layer of a SLAM run: the along-ray DBH fit lets the stem's
	 * centre drift linearly in time (the map's pose drift while the stem is
	 * seen; an odometry that under-estimates the distance walked squashes
	 * the stems passed by), under a Gaussian prior of this σ per axis
	 * [m/s]; a free drift over-corrects (doc/trees.md). 0.0002 since the
	 * odometry's stem model halved the scale error (0.0004 before). 0: off. */
	double dbh_drift_sigma_m_per_s = 0.0002;
	/** Tree layer of a SLAM run, multi-view DBH: stem-band voxels near
	 * breast height are kept per time segment of this many scans (0: off)
	 * and per range class, and the DBH circle of a blurred stem (fit RMSE
	 * above good_rmse_m) is finally fitted with one small shift per segment
	 * (refineCircleSegments), so pose errors between segments do not blur
	 * the ring. 100 scans (10 s): handheld DBH RMSE 1.49 -> 1.06 cm; 200
	 * (20 s) since 2026-12-04: fewer free shifts for a stem seen from one
	 * side, whose shifts and radius trade off (doc/trees.md). */
	int dbh_segment_scans = 200;
	/** Prior (1σ per axis) on a segment's shift. */
	double dbh_segment_shift_m = 0.05;
	/** Multi-view DBH: breast-height voxels are also kept per class of
	 * horizontal range from the sensor ([0, s), [s, 2s), [2s, 3s),
	 * beyond); the DBH is fitted on the nearest classes that cover
	 * good_arc_deg of the stem (rotation errors of the poses move far
	 * points most). 0: one class. */
	double dbh_range_step_m = 6;
	/** Half height of the band of the multi-view fit (narrower than
	 * dbh_band_half_m: a wrong lean estimate shears a tall band). */
	double dbh_segment_band_half_m = 0.15;
	/** Small stems seen along known rays: a fitted DBH below this is
	 * averaged with the silhouette estimate (silhouetteRadius: the lateral
	 * spread of the rays that hit the stem, blind to range noise), at half
	 * weight up to 3/4 of it and fading to none at it. On a 10-20 cm stem
	 * the range noise (2.5 cm) is a third of the radius and the along-ray
	 * fit trades the radius against the centre's range; the two estimates
	 * err apart (doc/trees.md). 0: off. */
	double dbh_silhouette_max_m = 0.20;
	int ransac_iterations = 300;
	double ransac_inlier_m = 0.015;
	uint32_t seed = 1;
	double arc_bin_deg = 5;

	// Quality flags (TreeQuality bits) and the top of the tree.
	double good_arc_deg = 120;
	double good_rmse_m = 0.02;
	double top_search_radius_m = 1.0;
	double top_max_gap_m = 1.5;

	// Tree layer of a SLAM run (TreeLayer): stem-band store and updates.
	bool layer_enabled = true;         ///< build the layer during `map`
	double layer_voxel_m = 0.02;       ///< stem-band voxel filter
	double layer_ground_cell_m = 0.5;  ///< lowest-point cells (terrain)
	double layer_min_hag_m = 0.25;     ///< band kept above the cell minimum
	double layer_max_hag_m = 3.6;
	double layer_max_range_m = 25;  ///< horizontal range of stored points
	/** A column is detected when the sensor is this far from its square. */
	double layer_complete_distance_m = 30;
	double layer_margin_m = 2;  ///< points from neighbouring columns
	/** Stem-band voxels of detected columns out of the sensor's reach go
	 * to an unnamed scratch file ($TMPDIR, else /tmp) and are read back
	 * when needed again: memory bounded by the area near the sensor. */
	bool layer_spill_to_disk = true;
	/** Detect a column's stems as soon as the sensor has left it ("true":
	 * trees during the run), or only once, at the end ("false": a
	 * long run detected every column again on every revisit and the
	 * final correction detected most of them once more; that was most
	 * of the tree layer's CPU). "auto": true for live input (`online`,
	 * `map --follow`), false for a recorded rawlog. */
	std::string layer_detect_during_run = "auto";
	/** During the run (layer_detect_during_run true), a column detected
	 * before is detected again once its stem-band store holds this many
	 * times the voxels it held at its last detection (a revisit that saw
	 * it as fully again); until then a loop correction moves its trees
	 * with the column, and the end of the run detects every column
	 * changed since. The robot run detected each column ~4 times in the
	 * run (every revisit, every correction): 3/4 of the live layer's CPU.
	 * 1: again after every change (trees always from all data so far). */
	double layer_redetect_growth = 2;
	/** For benchmarks: every column detection also writes its input to
	 * <dir>/column_<x>_<y>.bin (the directory is created), which
	 * bench_tree_detection replays. Empty: off. Big: a 7-minute walk
	 * writes about 2.4 GB. */
	std::string layer_dump_dir;
	/** layer_detect_during_run resolved for input that is (not) live. */
	bool detectDuringRun(bool live_input) const
	{
		return layer_detect_during_run == "auto"
		           ? live_input
		           : layer_detect_during_run == "true";
	}

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& section) const override;
};

}  // namespace forest_slam::trees
