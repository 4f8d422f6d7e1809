#pragma once
// Hierarchical k-means clustering of the non-ground points of a scan (paper
// §4.2): split with k-means (branching factor k) and recurse until every
// cluster holds at most `max_cluster_points` (the paper's sigma, 50..100);
// clusters left with fewer than `min_cluster_points` are merged into the
// nearest cluster. Each point gets a cluster id, its range and the size of
// its cluster, which the feature extraction uses (§4.3). Deterministic:
// initial centres are chosen by farthest-point sampling from the cluster's
// first point, no random numbers.
#include <mrpt/config/CLoadableOptions.h>

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace forest_slam::cluster
{
struct ClusterOptions : public mrpt::config::CLoadableOptions
{
	int branching_factor = 4;  ///< k of each k-means split
	int max_cluster_points =
	    80;  ///< sigma: split until a cluster is this small
	int min_cluster_points =
	    10;  ///< smaller clusters are merged into a neighbour
	int kmeans_iterations = 6;
	/** Small clusters farther than this from any other cluster centre stay
	 * on their own (an isolated thin stem must not be glued to a shrub). */
	double max_merge_distance_m = 0.5;
	/** A cluster wider than this (bounding-box diagonal) is split further
	 * whatever its size: sigma alone lets a few far returns of two stems
	 * end up in one small cluster (0 = size only) [m]. */
	double max_cluster_extent_m = 2.0;
	/** Threads splitting the root's groups (the caller's and threads-1
	 * short-lived ones); the clusters do not depend on it. */
	int threads = 2;

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& section) const override;
};

struct ClusterLabels
{
	std::vector<int32_t> cluster;  ///< per point; -1 = not clustered (NaN)
	std::vector<float> range_m;    ///< per point, distance to the origin
	std::vector<uint32_t> cluster_size;  ///< per point, members of its cluster
	std::vector<Eigen::Vector3f> centroids;  ///< per cluster id
	std::vector<uint32_t> sizes;             ///< per cluster id
	size_t clusterCount() const { return sizes.size(); }
};

/** Clusters `pts` (sensor frame, so range is |p|). */
ClusterLabels hierarchicalKMeans(const std::vector<Eigen::Vector3f>& pts,
                                 const ClusterOptions& opts = ClusterOptions());

}  // namespace forest_slam::cluster
