#pragma once
// What the outputs need from a mapping run beyond the CForestMap, collected
// scan by scan through one hook in the MappingPipeline:
//  - keyframes: a decimated, deskewed cloud with its sensor pose every N scans
//    or D metres (keyframes.simplemap; OctoMap ray casting at the end, so it
//    would follow later loop corrections of the keyframe poses);
//  - the dense map (DenseMap) for map.las / DTM / trees;
//  - GNSS epochs (report: GNSS coverage along the path);
//  - the odometry's ground lattice (classification, DTM) when there is one.
#include <forest_slam/core/scan_points.h>
#include <forest_slam/core/serial_worker.h>
#include <forest_slam/core/trajectory.h>
#include <forest_slam/outputs/dense_map.h>
#include <forest_slam/outputs/output_options.h>

#include <Eigen/Geometry>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

namespace mrpt::obs
{
class CObservation;
}
namespace forest_slam::ground
{
class GroundLattice;
}

namespace forest_slam::outputs
{
struct KeyframeCloud
{
	double t_s = 0;  ///< the scan's reference time (first firing)
	Eigen::Isometry3d sensor_pose = Eigen::Isometry3d::Identity();  ///< -> map
	std::vector<Eigen::Vector3f> points;  ///< sensor frame at t_s, deskewed
	/** With [outputs] spill_to_disk the points live in the collector's
	 * spill file instead (points empty): RunCollector::keyframeCloud. */
	uint64_t spill_offset = 0;
	size_t spill_count = 0;
	bool spilled = false;
	EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};
using Keyframes =
    std::vector<KeyframeCloud, Eigen::aligned_allocator<KeyframeCloud>>;
/** The points of keyframe i (writers that read clouds one at a time). */
using KeyframeCloudLoader = std::function<std::vector<Eigen::Vector3f>(size_t)>;

struct GnssEpoch
{
	double t_s = 0;
	int quality = 0;  ///< NMEA GGA fix quality: 0 none, 1 single, 2 DGPS,
	                  ///< 4 RTK fixed, 5 RTK float
	double lat_deg = 0, lon_deg = 0, alt_m = 0;
};

class RunCollector
{
   public:
	/** Returns outside [min_range_m, max_range_m] are never used (the
	 * pipeline's range gate: operator, vehicle body, sparse far points). */
	explicit RunCollector(const OutputOptions& o, double min_range_m = 0,
	                      double max_range_m = 1e9);

	/** One scan the odometry mapped: `scan` in the sensor frame, `pose` the
	 * lidar pose at its first firing, `deskewed` the scan's points (1:1 with
	 * scan.points) as the odometry deskewed them to the first firing (IMU
	 * rotation and accelerometer translation per firing column), so the
	 * outputs hold what was registered. Interpolating between consecutive
	 * scan poses instead misses the sway of a handheld rig within the sweep
	 * (stems 15 m away blurred by centimetres). `lattice` is the odometry's
	 * ground lattice (may be null); it must outlive this object.
	 * The scan is copied and collected on the collector's worker thread
	 * (every reader below waits for it); an error of that work is rethrown
	 * by the next call. */
	void addScan(const core::ScanPoints& scan, const core::StampedPose& pose,
	             const std::vector<Eigen::Vector3f>& deskewed,
	             const ground::GroundLattice* lattice);
	/** Same, with the lidar pose at any time of the sweep known (e.g. from
	 * a trajectory file): each firing column moves with its own pose. */
	void addScan(
	    const core::ScanPoints& scan, const core::StampedPose& pose,
	    const std::function<bool(double, Eigen::Isometry3d&)>& pose_at);
	/** A GNSS observation (CObservationGPS with a GGA message; others are
	 * ignored). */
	void addGnss(const mrpt::obs::CObservation& obs);

	/** Poses and times; the clouds through keyframeCloud (they may be on
	 * disk). */
	const Keyframes& keyframes() const
	{
		worker_.flush();
		return keyframes_;
	}
	/** The points of keyframe i (sensor frame), read back if spilled. */
	std::vector<Eigen::Vector3f> keyframeCloud(size_t i) const;
	/** Loop correction: the keyframe's sensor pose after the back-end. */
	void setKeyframePose(size_t i, const Eigen::Isometry3d& T)
	{
		worker_.flush();
		keyframes_.at(i).sensor_pose = T;
	}
	/** Loop correction of the dense map at the end of the run: every point
	 * moved by `move` (from its time: the correction of its scan), in
	 * place (DenseMap::transformPoints). No scan may be added after. */
	void transformDense(const std::function<void(DensePoint&)>& move);
	const DenseMap& dense() const
	{
		worker_.flush();
		return dense_;
	}
	const std::vector<GnssEpoch>& gnss() const { return gnss_; }
	const ground::GroundLattice* groundLattice() const { return lattice_; }
	const OutputOptions& options() const { return o_; }
	size_t scans() const
	{
		worker_.flush();
		return scans_;
	}
	/** Heap bytes of the keyframe clouds held in memory. */
	size_t keyframeBytes() const;
	/** Bytes moved to the spill file (dense tiles, keyframe clouds). */
	size_t spilledBytes() const;
	/** CPU time spent in addScan, total [s]. */
	double collectSeconds() const
	{
		worker_.flush();
		return collect_s_;
	}

   private:
	OutputOptions o_;
	float min_range_m_, max_range_m_;
	Keyframes keyframes_;
	DenseMap dense_;
	std::shared_ptr<core::SpillFile> spill_;  ///< created when first needed
	core::SpillFile& spill();
	std::vector<GnssEpoch> gnss_;
	const ground::GroundLattice* lattice_ = nullptr;
	size_t scans_ = 0, scans_since_keyframe_ = 0;
	// What the files asked for read (OutputOptions::needsDenseMap, ...);
	// with neither, addScan only counts the scan.
	bool collect_dense_, collect_keyframes_;
	bool have_prev_ = false;
	core::StampedPose prev_;
	double collect_s_ = 0;
	std::vector<Eigen::Isometry3f, Eigen::aligned_allocator<Eigen::Isometry3f>>
	    column_motion_;  // per firing column: sensor(t) -> sensor(t0)
	std::vector<uint8_t> column_done_;
	std::vector<Eigen::Vector3f> map_xyz_;  // per scan, reused
	std::vector<uint32_t> kept_;
	/** Runs collect() for addScan(..., deskewed, ...) off the mapping
	 * thread: the dense-map voxel table was a twelfth of a mapping run's
	 * CPU. Last member: joined before the rest goes. */
	mutable core::SerialWorker worker_;

	/** sensor(first firing) <- sensor(firing of p), once per column: from
	 * pose_at when it knows the time, else `motion` over the sweep. */
	const Eigen::Isometry3f& columnMotion(
	    const core::ScanPoint& p, const core::StampedPose& pose,
	    const Eigen::Isometry3d& motion, double sweep_s,
	    const std::function<bool(double, Eigen::Isometry3d&)>* pose_at);
	/** Deskewed points from `deskewed` when given, else per firing column
	 * from pose_at, else from the motion since the previous scan. */
	void collect(
	    const core::ScanPoints& scan, const core::StampedPose& pose,
	    const std::vector<Eigen::Vector3f>* deskewed,
	    const std::function<bool(double, Eigen::Isometry3d&)>* pose_at);
};

}  // namespace forest_slam::outputs
