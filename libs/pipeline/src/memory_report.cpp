#include <forest_slam/core/memory.h>
#include <forest_slam/pipeline/mapping_pipeline.h>
#include <forest_slam/pipeline/memory_report.h>

#include <cstdio>
#include <sstream>

namespace forest_slam::pipeline
{
MemorySample sampleMemory(const MappingPipeline& p)
{
	using core::toMb;
	MemorySample s;
	const auto& st = p.stats();
	s.data_s = st.dataSeconds();
	s.scans = st.scans_mapped;
	s.rss_mb = core::currentRssMb();
	const auto& col = p.outputCollector();
	s.dense_map_mb = toMb(col.dense().memoryBytes());
	s.dense_points = col.dense().size();
	s.keyframes_mb = toMb(col.keyframeBytes());
	s.spilled_mb = toMb(col.spilledBytes());
	s.forest_map_mb = toMb(p.forestMap().memoryBytes());
	s.map_voxels =
	    p.forestMap().edgePointCount() + p.forestMap().planarPointCount();
	if (const auto* t = p.treeLayer())
	{
		s.tree_layer_mb = toMb(t->memoryBytes());
		s.stem_voxels = t->stats().stored_voxels;
		s.spilled_mb += toMb(t->spilledBytes());
	}
	if (const auto* o = p.odometry())
	{
		s.local_map_mb = toMb(o->localMap().memoryBytes());
		s.ground_mb = toMb(o->groundLattice().nodes().memoryBytes());
	}
	if (const auto* b = p.backEnd())
	{
		s.back_end_mb = toMb(b->cloudBytes());
		s.spilled_mb += toMb(b->cloudBytesSpilled());
	}
	const core::HeapUse heap = core::heapUse();
	s.heap_in_use_mb = heap.in_use_mb;
	s.heap_free_mb = heap.free_mb;
	s.malloc_arenas = heap.arenas;
	s.trajectory_mb =
	    toMb(core::vectorBytes(p.trajectory()) + p.correctionBytes() +
	         core::vectorBytes(st.stage_ms) + core::vectorBytes(st.tree_ms) +
	         core::vectorBytes(st.backend_ms));
	return s;
}

std::string describeMemory(const MemorySample& s)
{
	char b[768];
	std::snprintf(
	    b, sizeof(b),
	    "RSS %.0f MB; dense map %.0f MB (%.2f M points), keyframes %.0f MB, "
	    "submaps %.0f MB (%.2f M voxels), tree layer %.0f MB (%.2f M "
	    "voxels), local map %.0f MB, ground %.0f MB, back-end %.0f MB, "
	    "trajectory %.0f MB; spilled to disk %.0f MB; malloc: %.0f MB in "
	    "use, %.0f MB free in its arenas (%d arenas)",
	    s.rss_mb, s.dense_map_mb, s.dense_points / 1e6, s.keyframes_mb,
	    s.forest_map_mb, s.map_voxels / 1e6, s.tree_layer_mb,
	    s.stem_voxels / 1e6, s.local_map_mb, s.ground_mb, s.back_end_mb,
	    s.trajectory_mb, s.spilled_mb, s.heap_in_use_mb, s.heap_free_mb,
	    s.malloc_arenas);
	return b;
}

namespace
{
void sampleJson(std::ostream& os, const MemorySample& s)
{
	os << "{\"data_s\": " << s.data_s << ", \"scans\": " << s.scans
	   << ", \"rss_mb\": " << s.rss_mb
	   << ", \"dense_map_mb\": " << s.dense_map_mb
	   << ", \"keyframes_mb\": " << s.keyframes_mb
	   << ", \"forest_map_mb\": " << s.forest_map_mb
	   << ", \"tree_layer_mb\": " << s.tree_layer_mb
	   << ", \"local_map_mb\": " << s.local_map_mb
	   << ", \"ground_mb\": " << s.ground_mb
	   << ", \"back_end_mb\": " << s.back_end_mb
	   << ", \"trajectory_mb\": " << s.trajectory_mb
	   << ", \"spilled_mb\": " << s.spilled_mb
	   << ", \"heap_in_use_mb\": " << s.heap_in_use_mb
	   << ", \"heap_free_mb\": " << s.heap_free_mb
	   << ", \"malloc_arenas\": " << s.malloc_arenas
	   << ", \"dense_points\": " << s.dense_points
	   << ", \"stem_voxels\": " << s.stem_voxels
	   << ", \"map_voxels\": " << s.map_voxels << "}";
}
}  // namespace

std::string memoryJson(const MemorySample& final_sample, double peak_rss_mb,
                       const std::vector<MemorySample>& curve)
{
	std::ostringstream os;
	os << "{\"peak_rss_mb\": " << peak_rss_mb << ", \"end_of_mapping\": ";
	sampleJson(os, final_sample);
	os << ", \"curve\": [";
	for (size_t i = 0; i < curve.size(); i++)
	{
		os << (i ? ", " : "");
		sampleJson(os, curve[i]);
	}
	os << "]}";
	return os.str();
}

}  // namespace forest_slam::pipeline
