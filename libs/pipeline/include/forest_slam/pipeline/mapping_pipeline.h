#pragma once
// The mapping pipeline, one observation at a time. Reads top to bottom like
// the paper's Fig. 1; stages join as they land (see doc/architecture.md):
//   lidar scan -> unpack (core) -> pose at every firing (pose source) ->
//   smoothness split edge/planar (map) -> deskew + insert into CForestMap.
#include <forest_slam/core/trajectory.h>
#include <forest_slam/loop/back_end.h>
#include <forest_slam/map/forest_map.h>
#include <forest_slam/outputs/run_collector.h>
#include <forest_slam/pipeline/mapping_config.h>
#include <forest_slam/pipeline/stream_checks.h>
#include <forest_slam/trees/tree_layer.h>
#include <mrpt/obs/CObservation.h>

#include <mrpt/poses/CPose3D.h>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <optional>

namespace mrpt::obs
{
class CObservationRotatingScan;
}

namespace forest_slam::pipeline
{
struct RunStats
{
	uint64_t observations = 0;
	uint64_t scans_in = 0;  ///< lidar observations seen
	uint64_t scans_mapped = 0;
	uint64_t scans_empty = 0;          ///< no valid return
	uint64_t scans_out_of_order = 0;   ///< time not after the previous scan
	uint64_t scans_outside_poses = 0;  ///< no pose for their time
	uint64_t scans_unreadable = 0;     ///< unknown model / malformed image
	uint64_t scans_degenerate = 0;     ///< odometry: weak geometry
	uint64_t scans_unregistered =
	    0;  ///< odometry: motion model carried the pose
	/** Online, pipeline behind the sensors: motion-model pose only, not
	 * registered nor inserted into the map (setLightScans). */
	uint64_t scans_light = 0;
	uint64_t scans_imu =
	    0;  ///< odometry: IMU rotation used for prediction + deskew
	uint64_t imu = 0, gnss = 0, other = 0;
	uint64_t imu_rejected = 0;  ///< non-finite or not after the previous sample
	uint64_t scans_duplicate =
	    0;  ///< same time as the previous scan (also out of order)
	uint64_t points_nonfinite = 0;  ///< NaN/inf points dropped
	uint64_t lidar_gaps = 0,
	         imu_gaps = 0;       ///< stalls of the stream (stream_checks.h)
	uint64_t gnss_rejected = 0;  ///< fixes that jumped (GnssJumpCheck)
	/** Odometry per-stage milliseconds, one entry per scan. */
	std::vector<odometry::ScanTiming> stage_ms;
	/** Tree layer milliseconds, one entry per mapped scan (store + the
	 * column detections that scan triggered), and the end-of-run pass. */
	std::vector<double> tree_ms;
	/** Back-end hook milliseconds on the mapping thread, one entry per
	 * scan mapped with a back-end: keyframes, corrections, and the waits
	 * for the map worker they need (a stall here holds a live run's
	 * scans back). */
	std::vector<double> backend_ms;
	double tree_finish_ms = 0;
	uint64_t points_in = 0;
	double first_stamp_s = 0, last_stamp_s = 0;
	double dataSeconds() const
	{
		return scans_in > 0 ? last_stamp_s - first_stamp_s : 0.0;
	}
};

class MappingPipeline
{
   public:
	/** `poses` is required when the config asks pose_source=trajectory. */
	MappingPipeline(const MappingConfig& cfg,
	                std::optional<core::Trajectory> poses = std::nullopt);
	/** Waits for the jobs still queued on the CForestMap's thread (they use
	 * the tree layer, which goes before the odometry's worker). */
	~MappingPipeline();

	/** Dispatches by sensor label; never throws on bad sensor data (it is
	 * counted and logged once), throws only on programming errors. */
	void process(const mrpt::obs::CObservation::Ptr& obs);

	/** Lidar pose per mapped scan at the scan's reference time (its first
	 * firing), in the map frame. */
	const core::Trajectory& trajectory() const { return trajectory_; }
	/** Heap bytes of the back-end's per-scan bookkeeping: the scans'
	 * anchors on their keyframes and the estimates kept for the in-run
	 * merges of the CForestMap and the tree layer (estimate, main thread
	 * only). */
	size_t correctionBytes() const;
	/** The map with every processed scan in it (waits for the odometry's
	 * map inserter thread). */
	const map::CForestMap& forestMap() const;
	/** The counters; tree_ms grows on the CForestMap's thread and is
	 * complete once forestMap() or finish() returned. */
	const RunStats& stats() const { return stats_; }
	const MappingConfig& config() const { return cfg_; }
	/** Keyframes, dense map and GNSS epochs for the output files. */
	const outputs::RunCollector& outputCollector() const { return outputs_; }
	bool reachedScanLimit() const;
	/** nullptr unless [loop] enabled (odometry pose source); final after
	 * finish(). */
	const loop::BackEnd* backEnd() const { return backend_.get(); }
	/** nullptr unless pose_source = odometry. */
	const odometry::LidarOdometry* odometry() const { return odometry_.get(); }
	/** The georeference the back-end estimated from GNSS (an
	 * `enu_origin` at the first fix with the estimated map->ENU transform),
	 * nullopt without GNSS estimate. Valid after finish(). */
	std::optional<outputs::GeoOptions> estimatedGeoreference() const;
	/** nullptr when [trees] layer_enabled = false. Waits for the layer's
	 * updates, which run on the CForestMap's thread (odometry). */
	const trees::TreeLayer* treeLayer() const;

	/** Online mode when the pipeline falls behind the sensors: while on,
	 * lidar scans get the pose a constant-velocity model extrapolates from
	 * the last two poses, and are neither registered nor inserted into the
	 * map (odometry pose source; the others are cheap and unaffected). */
	void setLightScans(bool on) { light_scans_ = on; }
	/** Lidar scans taken in but not posed yet (waiting for IMU samples). */
	size_t scansPending() const { return pending_.size(); }

	/** End of input: processes the scans still waiting for IMU samples,
	 * then the tree layer detects the columns not done yet. Call once after
	 * the last observation, before reading the results. */
	void finish();

   private:
	MappingConfig cfg_;
	std::optional<core::Trajectory> poses_;
	map::CForestMap map_;
	core::Trajectory trajectory_;
	RunStats stats_;
	bool have_last_scan_ = false;
	double last_scan_stamp_s_ = 0;
	// Stream plausibility (stream_checks.h): gaps are logged once, named
	// with their time; jumping GNSS fixes are logged and not used.
	GapDetector scan_gaps_{5.0, 0.5}, imu_gaps_{10.0, 0.1};
	GnssJumpCheck gnss_check_;
	void checkGnss(const mrpt::obs::CObservation& gnss);
	// Static pose source: gravity from the IMU samples seen before the first
	// scan levels the map frame (z up); frozen at the first scan.
	Eigen::Vector3d gravity_sum_vehicle_ = Eigen::Vector3d::Zero();
	uint64_t gravity_samples_ = 0;
	std::optional<Eigen::Isometry3d> static_pose_;
	std::unique_ptr<odometry::LidarOdometry> odometry_;
	bool light_scans_ = false;
	/** light_scan.cpp; false if it does not apply (then processed fully). */
	bool processLightScan(const mrpt::obs::CObservation& scan);
	// Odometry: IMU samples (body frame) and the scans waiting until the IMU
	// covers their sweep (a recording stores a scan at its first firing,
	// before the IMU samples taken during the sweep).
	imu::ImuBuffer imu_buffer_;
	struct PendingScan
	{
		core::ScanPoints pts;
		mrpt::poses::CPose3D sensor_pose;
	};
	std::deque<PendingScan> pending_;

	void addImuSample(const mrpt::obs::CObservation& imu);
	/** Runs the odometry on the pending scans whose sweep the IMU covers
	 * (all of them with `all`, or when too many wait: the IMU lags). */
	void drainPending(bool all);
	void runOdometry(PendingScan& s);
	outputs::RunCollector outputs_;

	void accumulateGravity(const mrpt::obs::CObservation& imu);
	/** First lidar pose in the map frame: at the origin, levelled with the
	 * IMU gravity seen before the first scan, heading along x. */
	Eigen::Isometry3d staticLidarPose(
	    const mrpt::poses::CPose3D& lidar_on_vehicle);
	void mapWithOdometry(const mrpt::obs::CObservationRotatingScan& scan,
	                     core::ScanPoints& pts);

	void processScan(const mrpt::obs::CObservationRotatingScan& scan);
	/** Removes NaN/inf points (logged once); false if none is left. */
	bool dropNonFinite(core::ScanPoints& pts);
	/** "t=... s (x s into the run)" for the log. */
	std::string when(double t_s) const;

	// Tree layer hook (tree_layer_hook.cpp): every mapped scan's points in
	// the map frame feed the layer, which updates map_'s trees.
	std::unique_ptr<trees::TreeLayer> tree_layer_;
	void feedTreeLayer(const std::vector<Eigen::Vector3f>& a,
	                   const std::vector<Eigen::Vector3f>& b,
	                   const Eigen::Vector3d& sensor);
	void feedTreeLayerOdometry(const Eigen::Isometry3d& scan_pose);
	void finishTreeLayer();
	/** End of the run (back_end_hook.cpp): the tree layer follows the
	 * final trajectory, its passes each with their own correction. */
	/** Moves the tree layer from where it is (`mapped`, the trajectory as
	 * mapped, with the poses of the last in-run merge) to trajectory_. */
	void correctTreeLayer(const core::Trajectory& mapped);
	/** Lidar pose in the map frame at absolute time t (--poses files hold
	 * lidar poses, like our own trajectory.tum, so they can be fed back). */
	bool lidarPoseAt(double t_s, Eigen::Isometry3d& out) const;

	// Back-end hook (back_end_hook.cpp): keyframes to loop::BackEnd, its
	// corrections applied at deterministic keyframes, GNSS fixes, drift
	// injection for the test bench; at the end every scan pose follows its
	// keyframe.
	std::unique_ptr<loop::BackEnd> backend_;
	struct ScanAnchor
	{
		size_t keyframe;
		Eigen::Isometry3d offset;  ///< keyframe^-1 scan, same frame
	};
	std::vector<ScanAnchor, Eigen::aligned_allocator<ScanAnchor>> anchors_;
	loop::Poses kf_pose_;  ///< keyframe poses in the current map frame
	double travelled_m_ = 0, next_inject_m_ = 0;
	std::optional<core::StampedPose> last_scan_pose_;
	struct PendingFix
	{
		double t_s;
		Eigen::Vector3d enu, sigma, antenna_on_vehicle;
	};
	std::deque<PendingFix> gnss_pending_;
	double last_gnss_fix_s_ = -1;  ///< time of the last fix passed on
	struct GnssOrigin;
	std::shared_ptr<GnssOrigin> gnss_origin_;
	/** CForestMap segments (CForestMap::startSegment): the first scan of
	 * each segment after the first; a new one starts after a correction
	 * that moves the map by more than half an edge voxel. Appended on the
	 * map worker (the segment starts there), read after a flush. */
	std::vector<size_t> map_segment_first_scan_;
	/** Poses of the first scans in the frame their CForestMap voxels are
	 * in since the last in-run merge of the segments (the back-end's
	 * estimate then); the later scans' voxels are where they were mapped
	 * (trajectory_). */
	std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>>
	    map_merged_pose_;
	/** CForestMap voxels after the last merge (set on the map worker,
	 * read after a flush). */
	size_t map_voxels_at_merge_ = 0;
	size_t map_merges_ = 0;  ///< in-run merges so far
	/** The back-end's estimate at an in-run merge of the tree layer, as
	 * currentEstimate() made it: the keyframes' poses and the correction
	 * of the scans after them. The scans' poses are made again from
	 * anchors_ (which never change) when a correction needs them, bit for
	 * bit: a pose per scan was kept before, 128 bytes a scan for every
	 * merge still in use (64 MB at 2100 s of the 60-minute run); the
	 * keyframes are one scan in ~9. */
	struct MergeEstimate
	{
		loop::Poses X;  ///< keyframe poses (emptied once unused)
		Eigen::Isometry3d C = Eigen::Isometry3d::Identity();
		size_t scans = 0;  ///< scans mapped at the merge
	};
	/** The same for the tree layer's stem-band voxels, merged on their
	 * own schedule (on the map worker) and column by column: the estimate
	 * at each in-run merge (merge v: tree_merge_estimates_[v - 1]; its
	 * keyframes freed once no column is last moved by it). A column last
	 * moved by merge v holds the voxels of the scans mapped before it
	 * where that estimate put them (TreeLayer::mergeVersion). */
	std::vector<MergeEstimate, Eigen::aligned_allocator<MergeEstimate>>
	    tree_merge_estimates_;
	size_t tree_voxels_at_merge_ = 0;
	size_t tree_merges_ = 0;
	/** The scans in the frame of the tree layer's columns last moved by
	 * merge `version` (0: as mapped). */
	core::Trajectory treeMapped(const core::Trajectory& as_mapped,
	                            uint32_t version) const;
	/** The tree layer's in-run merge in progress, moved a few columns per
	 * mapped scan (a step job on the map worker after each scan's
	 * insertion: the same steps in every run, whatever the timing). */
	struct TreeMerge;
	std::shared_ptr<TreeMerge> tree_merge_;
	/** Queues the next step of tree_merge_ (`max_voxels`: all the rest). */
	void stepTreeMerge(size_t max_voxels);
	/** Queues the rest of tree_merge_ as one job (at the end of the run,
	 * which reads the layer as a whole). */
	void completeTreeMerge();
	/** The back-end's estimate of every scan mapped so far, after the
	 * correction `C` with keyframe estimate `X`. */
	core::Trajectory currentEstimate(const loop::Poses& X,
	                                 const Eigen::Isometry3d& C) const;
	/** `mapped` (the scans as mapped) with its first `scans` poses
	 * replaced by the estimate (X, C), as currentEstimate() made it then. */
	core::Trajectory estimateOf(const core::Trajectory& mapped,
	                            const loop::Poses& X,
	                            const Eigen::Isometry3d& C, size_t scans) const;
	void initBackEnd();
	/** The dense map and the CForestMap follow the corrections: `mapped`
	 * is the trajectory as the scans were mapped. */
	void correctDenseMap(const core::Trajectory& mapped);
	/** Moves the CForestMap's voxels from where they are (`mapped`: the
	 * scans as mapped) to `target` and merges the segments into one. */
	void correctForestMap(const core::Trajectory& mapped,
	                      const core::Trajectory& target);
	/** correctForestMap as a job for the map worker, planned now (the map
	 * is read: call with the worker idle). */
	std::function<void(map::CForestMap&)> forestMapCorrection(
	    const core::Trajectory& mapped, const core::Trajectory& target);
	/** In the run, after the correction `C` (old map frame to new) with the
	 * back-end's keyframe estimate `X`: merges the CForestMap segments at
	 * that estimate when they hold half as many voxels again as after the
	 * last merge (each revisit after a correction copies what it sees);
	 * planned here, the voxels moved by a job on the map worker. */
	void mergeForestMapSegments(const core::Trajectory& now);
	/** Likewise the tree layer's passes (a job on the map worker) when
	 * the layer holds half as many stem voxels again as after the last. */
	void mergeTreeLayerPasses(const core::Trajectory& now, const loop::Poses& X,
	                          const Eigen::Isometry3d& C);
	/** After the odometry posed scan `s`: may move `pose` (correction). */
	void backEndScan(const PendingScan& s, core::StampedPose& pose);
	void backEndGnss(const mrpt::obs::CObservation& obs);
	void finishBackEnd();

   public:
	/** Levels a lidar orientation: R_level aligns the measured specific
	 * force (up, in the vehicle frame) with +z, then the heading is removed
	 * so x lies along the lidar's first heading. */
	static Eigen::Matrix3d levelledOrientation(
	    const Eigen::Vector3d& up_in_vehicle,
	    const Eigen::Matrix3d& lidar_on_vehicle);
};

}  // namespace forest_slam::pipeline
