#pragma once
// Scores the front-end (ground lattice -> hierarchical k-means -> features)
// on forest-sim scans against their per-point ground truth (gt_label,
// gt_tree layers; doc/simulator.md). Each scan is deskewed and placed with
// the ground-truth lidar poses interpolated at every firing time, so only
// the front-end is measured, not the odometry. The stages are called the
// way odometry::LidarOdometry::prepare calls them: ground in the
// gravity-aligned map frame, clusters and features in the frame of the
// first firing.
//
// Definitions (doc/frontend.md):
//  - ground precision = TP / (TP + FP), recall = TP / (TP + FN) over the
//    points within the lattice radius (horizontal distance <= radius_m; the
//    lattice does not label farther points, they are counted apart).
//  - tree mixing: a cluster is "mixed" when it holds points (stem, branch or
//    foliage) of two or more GT trees; the rate is mixed / clusters holding
//    points of at least one tree. Also reported weighted by points, and
//    restricted to stem points (clusters holding stem points of >= 2 trees).
//  - edge precision: fraction of edge features whose GT label is stem or
//    branch/foliage (gt_label 2 or 3), the "on stems/branches" of issue 5.
#include <forest_slam/cluster/hierarchical_kmeans.h>
#include <forest_slam/core/scan_points.h>
#include <forest_slam/core/trajectory.h>
#include <forest_slam/features/feature_extractor.h>
#include <forest_slam/ground/ground_lattice.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace forest_slam::frontend_eval
{
/** gt_label codes of forest-sim. */
enum GtLabel : uint16_t
{
	kNone = 0,
	kGround = 1,
	kStem = 2,
	kCrown = 3,  ///< branch or crown foliage
	kShrub = 4,
	kStructure = 5,
	kLabelCount = 6
};
const char* gtLabelName(uint16_t label);

struct FrontEndOptions
{
	ground::GroundOptions ground;
	cluster::ClusterOptions cluster;
	features::FeatureOptions features;
};

struct FrontEndScore
{
	size_t scans = 0;
	// Ground, counts over points within the lattice radius.
	uint64_t tp = 0, fp = 0, fn = 0, tn = 0;
	uint64_t beyond_radius = 0;  ///< points not labelled (too far)
	std::array<uint64_t, kLabelCount> fp_by_label{};  ///< labelled ground
	// Clusters.
	uint64_t tree_clusters = 0, mixed_clusters = 0;
	uint64_t tree_cluster_points = 0, mixed_cluster_points = 0;
	uint64_t stem_clusters = 0, mixed_stem_clusters = 0;
	uint64_t clusters = 0;
	// Features.
	uint64_t edges = 0, planar = 0;
	std::array<uint64_t, kLabelCount> edges_by_label{};
	// Per-scan stage times [ms].
	std::vector<double> ground_ms, cluster_ms, features_ms;

	double groundPrecision() const;
	double groundRecall() const;
	double mixingRate() const;  ///< mixed / tree clusters
	double mixingPointRate() const;
	double stemMixingRate() const;
	double edgeOnTreeFraction() const;  ///< labels stem + crown
	void add(const FrontEndScore& o);
	/** Several lines of text: every figure above. */
	std::string summary() const;
};

/** Runs the three stages on consecutive scans of one run, keeping the
 * ground lattice (and its temporal prior) between scans. */
class FrontEndScorer
{
   public:
	FrontEndScorer(const FrontEndOptions& o, const core::Trajectory& gt);

	/** Scores one scan (must carry gt_label and gt_tree layers). Returns
	 * false (and scores nothing) if the GT poses do not cover it. */
	bool addScan(const core::ScanPoints& scan);

	const FrontEndScore& score() const { return score_; }
	/** The last scored scan, point by point (valid points only). */
	struct Detail
	{
		std::vector<Eigen::Vector3f> in_map;  ///< deskewed, map frame
		std::vector<features::FeatureInputPoint> points;  ///< first firing
		std::vector<uint16_t> gt_label, gt_tree;
		std::vector<uint8_t> ground;
		features::Features feats;
		Eigen::Vector3d sensor_in_map;
	};
	const Detail& last() const { return last_; }
	const ground::GroundLattice& lattice() const { return lattice_; }

   private:
	FrontEndOptions o_;
	const core::Trajectory& gt_;
	ground::GroundLattice lattice_;
	FrontEndScore score_;
	Detail last_;
};

/** Scores the scans of `rawlog` (forest-sim output) with the GT poses of
 * `gt_tum`: scans [first_scan, first_scan + max_scans). */
FrontEndScore scoreRawlog(const std::string& rawlog, const std::string& gt_tum,
                          const FrontEndOptions& o, size_t first_scan = 0,
                          size_t max_scans = SIZE_MAX);

}  // namespace forest_slam::frontend_eval
