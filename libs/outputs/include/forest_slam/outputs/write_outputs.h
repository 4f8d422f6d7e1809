#pragma once
// Everything `forest-slam map --out DIR` writes at the end of a run, each
// file selectable in [outputs] and written atomically (doc/outputs.md).
#include <forest_slam/core/trajectory.h>
#include <forest_slam/map/forest_map.h>
#include <forest_slam/outputs/output_options.h>
#include <forest_slam/outputs/run_collector.h>
#include <forest_slam/trees/tree_options.h>

#include <string>
#include <utility>
#include <vector>

namespace forest_slam::outputs
{
struct RunFigures
{
	size_t scans = 0;
	double data_seconds = 0, wall_seconds = 0;
	int loop_closures = -1;  ///< negative: no loop-closure stage
};

struct OutputInputs
{
	const core::Trajectory& trajectory;
	const map::CForestMap& map;
	const RunCollector& collector;
	const OutputOptions& options;
	const GeoOptions& geo;
	const trees::TreeOptions& tree_options;
	RunFigures figures;
};

struct WrittenFile
{
	std::string path;
	std::string what;  ///< one line for listings
};

struct OutputSummary
{
	std::vector<WrittenFile> files;
	size_t trees = 0;
	bool trees_detected_here = false;  ///< tree layer was empty
	size_t dense_points = 0, keyframes = 0;
	double seconds = 0;
};

/** Writes the selected outputs into `dir` (which must exist). Throws
 * std::runtime_error naming the file on I/O errors. */
OutputSummary writeRunOutputs(const OutputInputs& in, const std::string& dir);

/** One line on what an output file is, by its name ("" if unknown). */
std::string describeOutput(const std::string& file_name);

/** Writes the CForestMap (gzip MRPT archive) atomically. */
void writeForestMap(const std::string& path, const map::CForestMap& m);

/** Peak resident memory of this process [MB]. */
double peakMemoryMb();

}  // namespace forest_slam::outputs
