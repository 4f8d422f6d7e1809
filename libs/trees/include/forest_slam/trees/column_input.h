#pragma once
// What one tree-layer column's stem detection reads, gathered by
// TreeLayer::findTrees from the column and its neighbours' margins, and the
// detection on it. With [trees] layer_dump_dir set, every detection also
// writes its input to a file, so that bench_tree_detection can replay the
// end-of-run detection of a real run without mapping it again (the same
// code, the same trees, timed alone).
#include <forest_slam/trees/stem_detector.h>

#include <Eigen/Core>

#include <string>
#include <vector>

namespace forest_slam::trees
{
struct ColumnInput
{
	/** The column's square: [x0, x0 + size_m) x [y0, y0 + size_m), map frame.
	 * Only trees centred in it are the column's. */
	double x0 = 0, y0 = 0, size_m = 0;
	std::vector<Eigen::Vector3d> ground;  ///< lowest points, for the DTM
	std::vector<Eigen::Vector3d> pts;     ///< stem band and the map above
	std::vector<Eigen::Vector3f> dirs;    ///< per point: viewing direction
	std::vector<float> times;             ///< per point: mean time [s]
	SegmentedPoints seg;  ///< breast-height points per time segment

	void clear();
	/** Frees the buffers whose capacity exceeds `points` elements. */
	void trim(size_t points);
};

/** The trees centred in the column's square: detectTrees on `in` with the
 * view directions, times and segments, over the terrain `dtm` (buildDtm of
 * in.ground). */
std::vector<map::TreeRecord> detectColumnTrees(const ColumnInput& in,
                                               const TerrainModel& dtm,
                                               const TreeOptions& o);

/** Writes `in` to `path` atomically (binary, this machine's byte order:
 * a benchmark format, not an exchange format). Throws std::runtime_error
 * naming the path on an I/O error, std::invalid_argument if the per-point
 * arrays differ in length. */
void writeColumnInput(const std::string& path, const ColumnInput& in);

/** Reads a file of writeColumnInput. Throws std::runtime_error naming the
 * path and what was expected if it cannot be read, is not such a file, is
 * truncated or its arrays disagree in length. */
ColumnInput readColumnInput(const std::string& path);

}  // namespace forest_slam::trees
