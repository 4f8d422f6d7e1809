#pragma once
// Cluster-aware LOAM feature extraction (paper §4.3): the smoothness of a
// point is computed only from its neighbours along the same ring *and in the
// same cluster*, so a stem edge is never "smoothed" by the shrub behind it;
// points with the highest values become edge features, the lowest planar
// features. Because in-cluster windows hide range jumps, foreground
// silhouettes (stem sides against the background) are added as edges
// explicitly; ground points feed the planar set. Per ring the scan is cut into
// sectors so features spread around the sensor (as LOAM does).
#include <mrpt/config/CLoadableOptions.h>

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace forest_slam::features
{
/** Range smoothing along the rings (range_smoothing.h). */
struct RangeSmoothingOptions
{
	/** Firings each side (0 = off): the window is 2 h + 1 consecutive
	 * firings of one ring. 2: the best of 2, 3 and 4 over ten forest-sim
	 * worlds (doc/odometry.md). */
	int half_window = 2;
	/** Neighbours in a run: the same cluster (or both ground), adjacent
	 * columns, ranges less than this apart [m]. */
	double max_step_m = 0.3;
};

struct FeatureOptions : public mrpt::config::CLoadableOptions
{
	int half_window = 5;  ///< neighbours each side (same ring, same cluster)
	double edge_threshold = 0.1;     ///< smoothness above: edge candidate
	double planar_threshold = 0.02;  ///< below: planar candidate
	int sectors_per_ring = 6;
	int max_edges_per_sector = 4;
	int max_planar_per_sector = 8;
	/** A point whose ring neighbour belongs to another cluster and lies this
	 * much farther away is on a foreground silhouette (a stem's side seen
	 * against the background): an edge, whatever its in-cluster smoothness.
	 * The background point beside it is not (it is the occluded side). */
	double silhouette_gap_m = 0.3;
	/** Edges only in clusters this linear: (s1 - s2) / s1 over the standard
	 * deviations along the cluster's two main axes (stems and branches are
	 * lines, shrubs and foliage blobs, walls planes); 0 = any cluster. */
	double edge_min_linearity = 0.6;
	/** Ground points kept as planar features: every N-th per ring. */
	int ground_decimation = 4;
	/** Planar features ranked by the smoothness of their neighbours without
	 * the point itself (the curvature of the window about the midpoint of
	 * its two nearest neighbours). Ranked by its own smoothness, a point is
	 * chosen where its range noise flattens the window: on a stem, whose
	 * bulge faces the sensor, that picks points lying behind the surface
	 * (4-16 mm at 3-12 m under 2.5 cm of noise), and the maps came out
	 * short (doc/odometry.md, "Planar points chosen without their own
	 * noise"). A planar point's own smoothness must still be below
	 * planar_threshold (outliers); edges keep the point's own smoothness. */
	bool planar_from_neighbours = true;
	/** Ranges smoothed along the rings for the odometry's matching and
	 * local map (range_smoothing.h; the features are chosen on the
	 * measured ranges). INI keys range_smoothing_half_window,
	 * range_smoothing_max_step_m. */
	RangeSmoothingOptions range_smoothing;

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& section) const override;
};

/** One point of the scan as the extractor needs it. */
struct FeatureInputPoint
{
	Eigen::Vector3f xyz;  ///< sensor frame (after deskew)
	uint16_t ring = 0;
	uint16_t column = 0;
	int32_t cluster = -1;  ///< -1 = not clustered (noise)
	bool ground = false;
};

struct Features
{
	std::vector<uint32_t> edges;    ///< indices into the input
	std::vector<uint32_t> planar;   ///< indices into the input
	std::vector<float> smoothness;  ///< per input point, -1 if not computed
};

/** A scan's finite points grouped by ring, each ring in firing (column)
 * order: ring r's points are index[start[r]] .. index[start[r + 1] - 1]. */
struct RingLines
{
	std::vector<uint32_t> start;  ///< rings() + 1 offsets into index
	std::vector<uint32_t> index;  ///< into the input points
	int rings() const { return static_cast<int>(start.size()) - 1; }
};
RingLines ringLines(const std::vector<FeatureInputPoint>& pts);

/** LOAM smoothness |sum_j (X_j - X_i)| / (|S| |X_i|) over the same-ring,
 * same-cluster window. */
Features extractFeatures(const std::vector<FeatureInputPoint>& pts,
                         const FeatureOptions& opts = FeatureOptions());
/** The same, with the scan's ring lines already built (ringLines(pts)). */
Features extractFeatures(const std::vector<FeatureInputPoint>& pts,
                         const RingLines& lines, const FeatureOptions& opts);

}  // namespace forest_slam::features
