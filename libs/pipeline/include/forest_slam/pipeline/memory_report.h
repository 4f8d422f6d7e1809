#pragma once
// Where a mapping run's memory goes: the resident set and the estimated
// bytes of each big container, sampled every [pipeline]
// memory_report_period_s of data (the curve of doc/performance.md) and at
// the end, logged and written to run_summary.json "memory".
#include <cstdint>
#include <string>
#include <vector>

namespace forest_slam::pipeline
{
class MappingPipeline;

struct MemorySample
{
	double data_s = 0;  ///< seconds of data mapped when sampled
	uint64_t scans = 0;
	double rss_mb = 0;  ///< resident set of the process now
	// Estimated heap of each container [MB] (core/memory.h).
	double dense_map_mb = 0;   ///< outputs: dense map (map.las) in memory
	double keyframes_mb = 0;   ///< outputs: keyframe clouds in memory
	double forest_map_mb = 0;  ///< CForestMap submaps (edge/planar voxels)
	double tree_layer_mb = 0;  ///< stem-band voxels, ground cells, trees
	double local_map_mb = 0;   ///< odometry's local map (radius-pruned)
	double ground_mb = 0;      ///< odometry's ground lattice
	double back_end_mb = 0;    ///< loop back-end keyframe clouds
	/** Poses and per-scan timings, the back-end's per-scan bookkeeping
	 * (MappingPipeline::correctionBytes). */
	double trajectory_mb = 0;
	double spilled_mb = 0;  ///< bytes moved to the spill files on disk
	// glibc's malloc over all arenas (core::heapUse): what the RSS holds
	// beyond the containers' estimates.
	double heap_in_use_mb = 0;  ///< handed out (containers + all the rest)
	/** Freed, kept by malloc for reuse; resident or not (releaseFreedHeap
	 * gives whole free pages back but they still count here). */
	double heap_free_mb = 0;
	int malloc_arenas = 0;
	uint64_t dense_points = 0, stem_voxels = 0, map_voxels = 0;
	double partsMb() const
	{
		return dense_map_mb + keyframes_mb + forest_map_mb + tree_layer_mb +
		       local_map_mb + ground_mb + back_end_mb + trajectory_mb;
	}
};

/** Reads the containers of `p` (call between observations). */
MemorySample sampleMemory(const MappingPipeline& p);
/** One log line: "RSS 812 MB; dense map 300 MB (2.3 M points), ...". */
std::string describeMemory(const MemorySample& s);
/** run_summary.json "memory": the final sample, the peak RSS and the
 * curve. */
std::string memoryJson(const MemorySample& final_sample, double peak_rss_mb,
                       const std::vector<MemorySample>& curve);

}  // namespace forest_slam::pipeline
