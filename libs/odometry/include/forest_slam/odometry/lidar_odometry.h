#pragma once
// Lidar odometry and mapping, one scan at a time (paper §4.1–4.6):
//   predict (IMU rotation + constant velocity, or constant velocity alone)
//   -> deskew every firing with the predicted motion ->
//   ground lattice (in the gravity-aligned map frame) -> hierarchical
//   k-means of non-ground points -> cluster-aware features ->
//   scan-to-map LM registration against the local map (incremental voxel
//   planes + edge points, IMU gravity prior on roll/pitch) -> insert the
//   scan into the local map and the CForestMap -> update velocity.
#include <forest_slam/cluster/hierarchical_kmeans.h>
#include <forest_slam/core/scan_points.h>
#include <forest_slam/core/serial_worker.h>
#include <forest_slam/core/trajectory.h>
#include <forest_slam/features/feature_extractor.h>
#include <forest_slam/ground/ground_lattice.h>
#include <forest_slam/imu/imu_buffer.h>
#include <forest_slam/map/forest_map.h>
#include <forest_slam/odometry/degeneracy.h>
#include <forest_slam/odometry/feature_registration.h>
#include <forest_slam/odometry/local_map.h>
#include <forest_slam/odometry/map_inserter.h>

#include <optional>

namespace forest_slam::odometry
{
struct OdometryOptions : public mrpt::config::CLoadableOptions
{
	/** The local map drops voxels beyond local_map.radius_m every this many
	 * scans. */
	int prune_every_scans = 20;
	/** Every scan is registered; every this many-th goes whole into the
	 * local map and the CForestMap, the others only with their points at
	 * least map_insert_far_m from the sensor (0: none). Every scan goes in
	 * whole until the lidar is start_radius_m from the first scan. Near
	 * the sensor consecutive scans of a 10 Hz lidar overlap almost wholly
	 * and the maps are full at their spacing; far points are new in every
	 * scan and hold the yaw. The tree layer and the dense map (map.las)
	 * take every scan. */
	int map_insert_every_scans = 1;
	double map_insert_far_m = 15.0;
	/** Use the IMU (when the rawlog has one) for the rotation prediction,
	 * the deskew and the gravity prior. */
	bool use_imu = true;
	/** Fewer matched features than this: the registration is not trusted
	 * and the motion model carries the pose (degenerate place). */
	int min_matches = 50;
	/** Smallest information eigenvalue relative to the largest below which
	 * the scan is reported degenerate; rotations count as the displacement
	 * they cause at the points' RMS range (scaledInformation, degeneracy.h).
	 * Forest scans stay above 0.04, ground-only scans fall to 0.02. */
	double degeneracy_ratio = 0.035;
	/** In a degenerate scan, directions whose (scaled) information is below
	 * this fraction of the largest keep the prediction (IMU rotation +
	 * constant velocity) instead of the registration (degeneracy.h); 0
	 * disables. Ground only: x, y and yaw at 0.02-0.06 of the largest. */
	double degenerate_hold_ratio = 0.1;
	/** Insert scans into the CForestMap on a worker thread while the next
	 * scan is registered (MapInserter); the map's content is the same. */
	bool async_map_insert = true;
	/** Translation in the prediction and the deskew from the accelerometer
	 * (velocity at the scan from the last two poses and the IMU, then the
	 * specific force integrated with the gyro's rotation) instead of
	 * constant velocity; needs use_imu. A handheld rig swings the lidar: its
	 * velocity changes within a sweep, and a constant-velocity deskew tilted
	 * each scan by up to 0.14 deg in roll (doc/odometry.md). */
	bool imu_translation = true;
	/** In a degenerate stretch the held directions follow the mean velocity
	 * of the last this many seconds of well-constrained scans, turned with
	 * the IMU's heading (meanVelocityStep, degeneracy.h), instead of the
	 * last scan's velocity (a walking gait changes it by 5 % from scan to
	 * scan); 0: the constant-velocity prediction. */
	double degenerate_velocity_window_s = 1.0;
	/** A scan no gyro covers (an IMU gap): the registration also estimates
	 * the sweep's motion (RegistrationPriors::edge_fraction), and the scan
	 * is re-deskewed with it before it goes into the maps. A handheld gait
	 * swings the lidar by 2-5 deg from one sweep to the next, so the
	 * constant-velocity deskew of such a scan is degrees off. */
	bool sweep_motion_without_imu = true;
	/** Rotation prior [deg] of the scans registered while the lidar has not
	 * yet gone start_radius_m from the first scan (0: the registration's
	 * prior_rotation_sigma_deg throughout). In those first metres the local
	 * map is seen from a single viewpoint, and the registration's yaw
	 * wanders by 0.01-0.05 deg, an offset the whole map keeps; the gyro,
	 * its bias taken at rest ([imu] standstill_bias), holds it better
	 * over those seconds. Needs the gyro of the scan. On forest-sim the
	 * start's yaw was held, the whole SLAM runs did not gain (the map's
	 * yaw then came from later on): off in the shipped INIs. */
	double start_rotation_sigma_deg = 0;
	double start_radius_m = 5.0;
	/** Within start_radius_m of the first scan, a planar match's k
	 * neighbours must span a plane: the middle eigenvalue of their spread
	 * at least this fraction of the largest (0: off). Seen from one
	 * viewpoint, the ground's neighbours lie along one ring, and the
	 * "plane" through a ring is a wall centred on that viewpoint (its tilt
	 * set by the terrain's roughness), which pulls the lidar back towards
	 * where it stood: the first 30 cm of motion lost 2-3 cm (forest-sim,
	 * noise-free scans too), an offset the whole map kept. */
	double start_plane_spread_ratio = 0;

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& section) const override;
};

struct OdometryConfig
{
	OdometryOptions odometry;           ///< [odometry]
	RegistrationOptions registration;   ///< [registration]
	LocalMapOptions local_map;          ///< [local_map]
	imu::AttitudeOptions imu;           ///< [imu]
	ground::GroundOptions ground;       ///< [ground]
	cluster::ClusterOptions cluster;    ///< [cluster]
	features::FeatureOptions features;  ///< [features]
};

struct ScanTiming
{
	double deskew_ms = 0, ground_ms = 0, cluster_ms = 0, features_ms = 0,
	       register_ms = 0, insert_ms = 0;
};

struct OdometryStep
{
	core::StampedPose pose;  ///< lidar pose at the scan's first firing
	size_t edges = 0, planar = 0;
	RegistrationResult registration;
	bool registered = false;  ///< false: first scan or motion model used
	bool degenerate = false;
	bool imu_used = false;  ///< IMU rotation for prediction and deskew
	ScanTiming timing;
};

/** Motion of the sensor during a sweep: pose at time s after the first
 * firing, relative to the first firing. Translation (and, without IMU,
 * rotation) from the constant-velocity model; with the IMU the rotation is
 * the integrated gyro. */
struct SweepMotion
{
	Eigen::Isometry3d end =
	    Eigen::Isometry3d::Identity();    ///< constant velocity, whole sweep
	const imu::ImuBuffer* imu = nullptr;  ///< rotation from the gyro when set
	/** With imu set: the translation from the velocity at t0 and the
	 * accelerometer (both in the body frame at t0) instead of `end`. */
	bool accel = false;
	Eigen::Vector3d v0_body = Eigen::Vector3d::Zero();
	Eigen::Vector3d gravity_body = Eigen::Vector3d::Zero();
	Eigen::Matrix3d R_body_lidar = Eigen::Matrix3d::Identity();
	double t0_s = 0;  ///< absolute time of the first firing
	double sweep_s = 0.1;
	Eigen::Isometry3d at(double s) const;
};

/** Deskews a scan into the frame of its first firing (one transform per
 * firing column); non-finite points are dropped. `times_s` (optional) gets
 * each output point's firing time after the first firing. */
std::vector<features::FeatureInputPoint> deskewScan(
    const core::ScanPoints& scan, const SweepMotion& motion,
    std::vector<float>* times_s = nullptr);

/** Marks the ground points (labels of GroundLattice::labelScan, same order)
 * and gives every other point the id of its hierarchical k-means cluster;
 * returns the number of clusters. */
size_t labelGroundAndCluster(std::vector<features::FeatureInputPoint>& pts,
                             const std::vector<uint8_t>& ground,
                             const cluster::ClusterOptions& o);

class LidarOdometry
{
   public:
	LidarOdometry(const OdometryConfig& cfg, map::CForestMap& map);

	/** The first scan's pose (default identity): e.g. levelled with gravity
	 * from the IMU. Must be called before the first processScan. */
	void setInitialPose(const Eigen::Isometry3d& T) { initial_pose_ = T; }

	/** IMU samples (body frame) and the lidar's mount on the body: enables
	 * the IMU rotation prediction, deskew and gravity prior. */
	void setImu(const imu::ImuBuffer* imu, const Eigen::Matrix3d& R_body_lidar)
	{
		imu_ = imu;
		R_body_lidar_ = R_body_lidar;
	}

	OdometryStep processScan(const core::ScanPoints& scan);

	/** Back-end hook: the map frame estimate moved by `C` (a loop closure or
	 * GNSS correction, p' = C p). The last pose and the local map follow,
	 * so that drift does not re-accumulate, and the map-frame velocity of
	 * the accelerometer's prediction turns with them (the relative
	 * velocity needs nothing). The CForestMap and the ground lattice are
	 * not moved. */
	void applyCorrection(const Eigen::Isometry3d& C);

	/** Returns when every processed scan is in the CForestMap (insertion
	 * runs on a worker thread, MapInserter): call before reading the map. */
	void flushMap() { inserter_.flush(); }
	/** Queues work on the CForestMap's thread, after the insertion of every
	 * scan processed so far (MapInserter::run); flushMap() waits for it. */
	void runOnMap(std::function<void(map::CForestMap&)> job)
	{
		inserter_.run(std::move(job));
	}

	const ground::GroundLattice& groundLattice() const { return lattice_; }
	/** The odometry's local map (waits for the last scan's insertion). */
	const LocalMap& localMap() const
	{
		local_worker_.flush();
		return local_map_;
	}
	size_t scansProcessed() const { return scans_; }
	/** The last scan's finite points (1:1 with its ScanPoints when the
	 * caller dropped non-finite ones) deskewed to its first firing, in the
	 * lidar frame, with the motion its registration used. The tree layer
	 * and the output collector take them rather than re-deskewing between
	 * scan poses, which would miss the rotation and velocity changes within
	 * the sweep. */
	const std::vector<Eigen::Vector3f>& lastDeskewed() const
	{
		return last_deskewed_;
	}

   private:
	/** A deskewed scan with its labels and features. */
	struct Prepared
	{
		std::vector<features::FeatureInputPoint> points;
		features::Features feats;
		/** Each point's position for matching and the local map: its range
		 * smoothed along the ring (features/range_smoothing.h). The
		 * CForestMap and the tree layer get the points as measured. */
		std::vector<Eigen::Vector3f> matched;
		std::vector<Eigen::Vector3f> edges, planar;  ///< selected features
		/** Firing time of each selected feature as a fraction of the
		 * sweep. */
		std::vector<float> edge_fraction, planar_fraction;
	};
	Prepared prepare(const core::ScanPoints& scan, const SweepMotion& motion,
	                 const Eigen::Isometry3d& predicted, ScanTiming& timing);
	/** Into both maps: the points of `s` at least min_range_m from the
	 * sensor. */
	void insert(const Prepared& s, const Eigen::Isometry3d& pose,
	            float min_range_m = 0);
	/** Lidar rotation from t0 to t1 from the IMU (lidar frame). */
	Eigen::Matrix3d imuRotation(double t0_s, double t1_s) const;
	/** Gravity vector of the map frame (z up) [m/s^2]. */
	Eigen::Vector3d gravityInMap() const;
	/** The accelerometer from the last scan to stamp_s, in the body frame
	 * at the last scan; R_map_body is that frame's orientation. */
	imu::AccelIntegral accelSinceLastScan(double stamp_s,
	                                      Eigen::Matrix3d& R_map_body) const;

	OdometryConfig cfg_;
	LocalMap local_map_;
	const imu::ImuBuffer* imu_ = nullptr;
	Eigen::Matrix3d R_body_lidar_ = Eigen::Matrix3d::Identity();
	std::optional<core::ScanPoints> first_scan_;  ///< until the motion is known
	bool first_scan_imu_ = false;  ///< the first scan was deskewed with the IMU
	map::CForestMap& map_;
	MapInserter inserter_;  ///< after map_: joined before the map goes
	/** Inserts each scan into local_map_ (and prunes it) while the next
	 * scan is read, deskewed, labelled and clustered, which do not read the
	 * local map; flushed before anything does. After local_map_. */
	mutable core::SerialWorker local_worker_;
	ground::GroundLattice lattice_;
	Eigen::Isometry3d initial_pose_ = Eigen::Isometry3d::Identity();
	Eigen::Isometry3d last_pose_ = Eigen::Isometry3d::Identity();
	/** velocity_ comes from well-constrained registrations (or was held
	 * through a degenerate stretch that followed them): only then may the
	 * prediction hold a degenerate scan's weak directions. */
	bool velocity_trusted_ = false;
	Eigen::Isometry3d velocity_ =
	    Eigen::Isometry3d::Identity();  ///< per scan period
	double last_stamp_s_ = 0, last_period_s_ = 0.1;
	/** Lidar velocity at last_stamp_s_ in the map frame (imu_translation),
	 * valid when velocity_map_known_. */
	Eigen::Vector3d velocity_map_ = Eigen::Vector3d::Zero();
	bool velocity_map_known_ = false;
	/** The recent poses (at most kTrackSize): the mean velocity before a
	 * degenerate stretch. */
	std::deque<TrackPoint> track_;
	static constexpr size_t kTrackSize = 200;
	std::vector<Eigen::Vector3f> last_deskewed_;
	size_t scans_ = 0;
	/** The lidar has been start_radius_m from the first scan. */
	bool left_start_ = false;
};

}  // namespace forest_slam::odometry
