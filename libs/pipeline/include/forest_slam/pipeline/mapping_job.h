#pragma once
// A whole offline run: stream a rawlog through the MappingPipeline, show
// progress, stop cleanly on SIGINT/SIGTERM or damaged input, and write every
// output atomically into the output folder.
#include <forest_slam/pipeline/mapping_config.h>
#include <forest_slam/pipeline/mapping_pipeline.h>
#include <forest_slam/pipeline/memory_report.h>
#include <forest_slam/pipeline/observation_source.h>

#include <string>

namespace forest_slam::pipeline
{
struct MappingJob
{
	std::string config_path;
	std::string rawlog_path;
	std::string out_dir;
	std::string poses_path;	 ///< optional TUM file (pose_source=trajectory)
	int progress_tty = -1;	///< -1 auto, 0 log lines, 1 bar
	/** Keep reading as the rawlog grows (another process writes it); the
	 * run ends once it did not grow for follow_timeout_s, or on SIGINT. */
	bool follow = false;
	double follow_timeout_s = 10.0;
};

struct MappingResult
{
	RunStats stats;
	double wall_seconds = 0;
	bool input_damaged = false;	 ///< stopped at a damaged record
	bool interrupted = false;  ///< SIGINT/SIGTERM
	std::string damage_message;
	std::vector<std::string> outputs;  ///< files written
	/** Memory every [pipeline] memory_report_period_s of data, and at the
	 * end of mapping (before the outputs are written). */
	std::vector<MemorySample> memory_curve;
	MemorySample memory_end;
	/** CPU time of each thread (summed by name) when the last scan was
	 * processed, before the final corrections and the end-of-run
	 * detection: where the scans' CPU goes [s]. */
	std::vector<std::pair<std::string, double>> scan_thread_cpu_s;
};

/** Runs the job. Throws core::ConfigError / std::runtime_error for problems
 * found before processing starts (bad config, unreadable input). Damage
 * found mid-way does not throw: processing stops there, outputs are written
 * for what was processed and `input_damaged` is set. */
MappingResult runMapping(const MappingJob& job);

/** The same run over any source of observations (job.rawlog_path, follow
 * and progress_tty are then the source's business). */
MappingResult runMapping(const MappingJob& job, const MappingConfig& cfg,
						 ObservationSource& source);

/** Writes the outputs selected in [outputs] (outputs::writeRunOutputs:
 * trajectory, keyframes, forest.map, LAS, OctoMap, trees, DTM, report) and
 * run_summary.json into `out_dir`; returns the paths written. */
std::vector<std::string> writeOutputs(const MappingPipeline& p,
                                      const MappingResult& r,
                                      const std::string& out_dir);

/** Reads a forest.map written by writeOutputs. */
std::shared_ptr<map::CForestMap> loadForestMap(const std::string& path);

}  // namespace forest_slam::pipeline
