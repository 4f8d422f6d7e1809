#pragma once
// Lidar odometry and mapping, one scan at a time (paper §4.1–4.6):
//   predict (constant velocity) -> deskew with the predicted motion ->
//   ground lattice (in the gravity-aligned map frame) -> hierarchical
//   k-means of non-ground points -> cluster-aware features ->
//   scan-to-map LM registration against the CForestMap submaps near the
//   predicted pose -> insert the features into the map -> update velocity.
#include <forest_slam/cluster/hierarchical_kmeans.h>
#include <forest_slam/core/scan_points.h>
#include <forest_slam/core/trajectory.h>
#include <forest_slam/features/feature_extractor.h>
#include <forest_slam/ground/ground_lattice.h>
#include <forest_slam/map/forest_map.h>
#include <forest_slam/odometry/feature_registration.h>

#include <optional>

namespace forest_slam::odometry
{
struct OdometryOptions : public mrpt::config::CLoadableOptions
{
	double local_map_radius_m = 40.0;  ///< submaps used for scan-to-map
	/** The local map's search structure is rebuilt when the sensor moved
	 * this far from where it was built, or after this many scans: building
	 * k-d trees over the local map is the costliest step of a scan. */
	double target_rebuild_distance_m = 0.5;
	int target_rebuild_scans = 5;
	/** Fewer matched features than this: the registration is not trusted
	 * and the motion model carries the pose (degenerate place). */
	int min_matches = 50;
	/** Smallest information eigenvalue relative to the largest below which
	 * the scan is reported degenerate. */
	double degeneracy_ratio = 1e-3;

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
							const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
						  const std::string& section) const override;
};

struct OdometryConfig
{
	OdometryOptions odometry;		 ///< [odometry]
	RegistrationOptions registration;  ///< [registration]
	ground::GroundOptions ground;	 ///< [ground]
	cluster::ClusterOptions cluster;  ///< [cluster]
	features::FeatureOptions features;	///< [features]
};

struct ScanTiming
{
	double deskew_ms = 0, ground_ms = 0, cluster_ms = 0, features_ms = 0,
		   register_ms = 0, insert_ms = 0;
};

struct OdometryStep
{
	core::StampedPose pose;	 ///< lidar pose at the scan's first firing
	size_t edges = 0, planar = 0;
	RegistrationResult registration;
	bool registered = false;  ///< false: first scan or motion model used
	bool degenerate = false;
	ScanTiming timing;
};

class LidarOdometry
{
   public:
	LidarOdometry(const OdometryConfig& cfg, map::CForestMap& map);

	/** The first scan's pose (default identity): e.g. levelled with gravity
	 * from the IMU. Must be called before the first processScan. */
	void setInitialPose(const Eigen::Isometry3d& T) { initial_pose_ = T; }

	OdometryStep processScan(const core::ScanPoints& scan);

	const ground::GroundLattice& groundLattice() const { return lattice_; }
	size_t scansProcessed() const { return scans_; }

   private:
	/** A deskewed scan with its labels and features. */
	struct Prepared
	{
		std::vector<features::FeatureInputPoint> points;
		features::Features feats;
		std::vector<Eigen::Vector3f> edges, planar;	 ///< selected features
	};
	Prepared prepare(const core::ScanPoints& scan, const Eigen::Isometry3d& motion,
					 const Eigen::Isometry3d& predicted, ScanTiming& timing);
	void insert(const Prepared& s, const Eigen::Isometry3d& pose);
	RegistrationResult registerToMap(const Prepared& s, const Eigen::Isometry3d& predicted);

	OdometryConfig cfg_;
	FeatureTarget target_;
	Eigen::Vector3d target_centre_ = Eigen::Vector3d::Zero();
	int scans_since_target_ = -1;  ///< -1: no target yet
	std::optional<core::ScanPoints> first_scan_;  ///< until the motion is known
	map::CForestMap& map_;
	ground::GroundLattice lattice_;
	Eigen::Isometry3d initial_pose_ = Eigen::Isometry3d::Identity();
	Eigen::Isometry3d last_pose_ = Eigen::Isometry3d::Identity();
	Eigen::Isometry3d velocity_ = Eigen::Isometry3d::Identity();  ///< per scan period
	double last_stamp_s_ = 0, last_period_s_ = 0.1;
	size_t scans_ = 0;
};

}  // namespace forest_slam::odometry
