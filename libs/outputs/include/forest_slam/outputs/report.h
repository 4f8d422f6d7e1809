#pragma once
// report.html: one self-contained page (inline SVG, no script, no network)
// for a forester and a roboticist: top view of the trajectory and the trees
// as circles scaled by DBH (paper Fig. 12), DBH histogram, stand table,
// GNSS coverage along the path, loop closures and processing figures.
#include <forest_slam/core/trajectory.h>
#include <forest_slam/map/forest_map.h>
#include <forest_slam/outputs/run_collector.h>

#include <string>
#include <utility>
#include <vector>

namespace forest_slam::outputs
{
/** Stand figures per hectare (forest inventory conventions). */
struct StandTable
{
	double area_ha = 0;
	size_t stems = 0;
	double stems_per_ha = 0, basal_area_m2_per_ha = 0;
	double mean_dbh_m = 0, quadratic_mean_dbh_m = 0;
	struct DbhClass
	{
		double lo_m = 0, hi_m = 0;
		size_t stems = 0;
		double stems_per_ha = 0, basal_area_m2_per_ha = 0;
	};
	std::vector<DbhClass> classes;
};

/** DBH classes of class_width_m from 0 up to the largest tree. */
StandTable standTable(const std::vector<map::TreeRecord>& trees, double area_m2,
                      double class_width_m = 0.1);

/** Share of the path length (0..1) per GGA fix quality, the key -1 meaning
 * "no GNSS epoch within max_gap_s of the pose". */
std::vector<std::pair<int, double>> gnssCoverage(
    const core::Trajectory& traj, const std::vector<GnssEpoch>& gnss,
    double max_gap_s = 1.5);

struct ReportInputs
{
	const core::Trajectory* trajectory = nullptr;
	const std::vector<map::TreeRecord>* trees = nullptr;
	const std::vector<GnssEpoch>* gnss = nullptr;
	std::string trees_source;  ///< "tree layer" / "detected on the dense map"
	double area_m2 = 0;        ///< mapped ground area (stand table denominator)
	std::string crs;           ///< "" when not georeferenced
	// Processing figures.
	size_t scans = 0;
	double data_seconds = 0, wall_seconds = 0, peak_memory_mb = 0;
	double collect_ms_per_scan = 0;  ///< output collectors' share
	size_t keyframes = 0, dense_points = 0;
	/** Loop closures accepted; negative: no loop-closure stage ran. */
	int loop_closures = -1;
	std::vector<std::pair<std::string, std::string>> files;  ///< name, what
};

void writeReport(const std::string& path, const ReportInputs& in);

}  // namespace forest_slam::outputs
