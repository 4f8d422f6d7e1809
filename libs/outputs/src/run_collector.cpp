#include <forest_slam/core/memory.h>
#include <forest_slam/outputs/run_collector.h>

#include <mrpt/obs/CObservationGPS.h>
#include <mrpt/system/datetime.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <optional>
#include <stdexcept>
#include <string>

namespace forest_slam::outputs
{
namespace
{
/** CPU time of this thread: the collectors' cost without the waits of a
 * machine shared with other jobs. */
double threadCpuSeconds()
{
	timespec ts{};
	clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
	return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/** Scans queued for the collector at most (each a copy of the scan and its
 * deskewed points, ~1.3 MB for a VLP-16). The collector runs at a low
 * priority (nice 19 for a recorded rawlog); with 2 the odometry waited for
 * it 7.6 s of the robot run's 170 s (doc/performance.md, forty-seventh
 * session). */
constexpr size_t kCollectorQueue = 32;
}  // namespace

RunCollector::RunCollector(const OutputOptions& o, double min_range_m,
                           double max_range_m)
    : o_(o),
      min_range_m_(static_cast<float>(min_range_m)),
      max_range_m_(static_cast<float>(max_range_m)),
      dense_(o.dense_voxel_m, o.spill_to_disk ? o.dense_tile_m : 0),
      collect_dense_(o.needsDenseMap()),
      collect_keyframes_(o.needsKeyframeClouds()),
      worker_(kCollectorQueue, "fs-collector", true)
{
	// At once, so a bad spill_dir stops the run before it starts.
	if (o.spill_to_disk) spill();
}

core::SpillFile& RunCollector::spill()
{
	if (!spill_) spill_ = std::make_shared<core::SpillFile>(o_.spill_dir);
	return *spill_;
}

std::vector<Eigen::Vector3f> RunCollector::keyframeCloud(size_t i) const
{
	worker_.flush();
	const auto& kf = keyframes_.at(i);
	if (!kf.spilled) return kf.points;
	std::vector<Eigen::Vector3f> pts;
	spill_->readVector(kf.spill_offset, kf.spill_count, pts);
	return pts;
}

size_t RunCollector::spilledBytes() const
{
	worker_.flush();
	return spill_ ? spill_->size() : 0;
}

void RunCollector::addScan(const core::ScanPoints& scan,
                           const core::StampedPose& pose,
                           const std::vector<Eigen::Vector3f>& deskewed,
                           const ground::GroundLattice* lattice)
{
	if (lattice) lattice_ = lattice;
	if (deskewed.size() != scan.points.size())
		throw std::invalid_argument(
		    "RunCollector::addScan: " + std::to_string(deskewed.size()) +
		    " deskewed points for a scan of " +
		    std::to_string(scan.points.size()));
	// Not even copied when no file reads it (the copy is on the caller's
	// thread, the mapping thread).
	if (!collect_dense_ && !collect_keyframes_)
	{
		scans_++;  // no job was ever queued: nothing races with it
		return;
	}
	worker_.push([this, scan, pose, deskewed]
	             { collect(scan, pose, &deskewed, nullptr); });
}

void RunCollector::addScan(
    const core::ScanPoints& scan, const core::StampedPose& pose,
    const std::function<bool(double, Eigen::Isometry3d&)>& pose_at)
{
	worker_.flush();  // pose_at reads the caller's state: collected here
	if (!collect_dense_ && !collect_keyframes_)
	{
		scans_++;
		return;
	}
	collect(scan, pose, nullptr, &pose_at);
}

const Eigen::Isometry3f& RunCollector::columnMotion(
    const core::ScanPoint& p, const core::StampedPose& pose,
    const Eigen::Isometry3d& motion, double sweep_s,
    const std::function<bool(double, Eigen::Isometry3d&)>* pose_at)
{
	if (p.column >= column_done_.size())
	{
		column_done_.resize(p.column + 1, 0);
		column_motion_.resize(p.column + 1);
	}
	if (!column_done_[p.column])
	{
		Eigen::Isometry3d T_col;
		if (pose_at && (*pose_at)(pose.t_s + p.t_s, T_col))
			T_col = pose.pose.inverse() * T_col;
		else
			T_col = core::interpolateIsometry(
			    Eigen::Isometry3d::Identity(), motion,
			    std::clamp(p.t_s / sweep_s, 0.0, 1.0));
		column_motion_[p.column] = T_col.cast<float>();
		column_done_[p.column] = 1;
	}
	return column_motion_[p.column];
}

void RunCollector::collect(
    const core::ScanPoints& scan, const core::StampedPose& pose,
    const std::vector<Eigen::Vector3f>* deskewed,
    const std::function<bool(double, Eigen::Isometry3d&)>* pose_at)
{
	const double cpu0 = threadCpuSeconds();
	if (scans_ == 0) dense_.setTimeOrigin(pose.t_s);

	// Motion over the sweep from the previous pose (constant velocity).
	Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
	if (have_prev_ && pose.t_s - prev_.t_s > 1e-3 && scan.sweep_s > 0)
		motion = core::interpolateIsometry(
		    Eigen::Isometry3d::Identity(), prev_.pose.inverse() * pose.pose,
		    scan.sweep_s / (pose.t_s - prev_.t_s));

	const bool keyframe =
	    collect_keyframes_ &&
	    (keyframes_.empty() ||
	     scans_since_keyframe_ + 1 >=
	         static_cast<size_t>(o_.keyframe_every_scans) ||
	     (pose.pose.translation() - keyframes_.back().sensor_pose.translation())
	             .norm() >= o_.keyframe_every_m);
	std::optional<DenseMap> kf_grid;
	if (keyframe) kf_grid.emplace(o_.keyframe_voxel_m);

	const Eigen::Isometry3f T = pose.pose.cast<float>();
	const double sweep = std::max(1e-6, scan.sweep_s);
	const float t_offset = static_cast<float>(pose.t_s - dense_.timeOrigin());
	const float dense_r = static_cast<float>(o_.dense_max_range_m);
	const float kf_r = static_cast<float>(o_.keyframe_max_range_m);
	constexpr float kRadToLasAngle = static_cast<float>(180.0 / M_PI / 0.006);
	std::fill(column_done_.begin(), column_done_.end(), 0);
	// 1. Deskew into the frame of the first firing, range gates.
	const auto& pts = scan.points;
	map_xyz_.clear();
	kept_.clear();
	for (uint32_t i = 0; i < pts.size(); i++)
	{
		const auto& p = pts[i];
		if (!(p.range_m >= min_range_m_ && p.range_m <= max_range_m_)) continue;
		const Eigen::Vector3f s =
		    deskewed ? (*deskewed)[i]
		             : columnMotion(p, pose, motion, sweep, pose_at) *
		                   Eigen::Vector3f(p.x, p.y, p.z);
		if (kf_grid && p.range_m <= kf_r) kf_grid->claim(s);
		if (!collect_dense_ || p.range_m > dense_r) continue;
		map_xyz_.push_back(T * s);  // map frame from here on
		kept_.push_back(i);
	}
	// 2. Dense map. Its table is far larger than the CPU caches: prefetch
	// the slots of the points kPrefetch ahead.
	constexpr size_t kPrefetch = 24;
	for (size_t n = 0; n < kept_.size(); n++)
	{
		if (n + kPrefetch < kept_.size())
			dense_.prefetch(map_xyz_[n + kPrefetch]);
		DensePoint* d = dense_.claim(map_xyz_[n]);
		if (!d) continue;  // the voxel already holds a point
		const auto& p = pts[kept_[n]];
		d->t_s = t_offset + p.t_s;
		d->intensity = static_cast<uint16_t>(
		    std::clamp(p.intensity, 0.0f, 255.0f) * 256.0f);
		d->scan_angle = static_cast<int16_t>(std::lround(
		    std::atan2(p.z, std::hypot(p.x, p.y)) * kRadToLasAngle));
	}
	if (kf_grid)
	{
		KeyframeCloud kf;
		kf.t_s = pose.t_s;
		kf.sensor_pose = pose.pose;
		kf.points.reserve(kf_grid->size());
		for (const auto& k : kf_grid->points()) kf.points.push_back(k.xyz);
		if (o_.spill_to_disk)  // needed again only at the end of the run
		{
			kf.spill_offset = spill().appendVector(kf.points);
			kf.spill_count = kf.points.size();
			kf.spilled = true;
			std::vector<Eigen::Vector3f>().swap(kf.points);
		}
		keyframes_.push_back(std::move(kf));
		scans_since_keyframe_ = 0;
	}
	else
		scans_since_keyframe_++;
	// Tiles no return of this sensor position can reach go to disk (the
	// margin keeps a tile at the edge from going back and forth).
	if (o_.spill_to_disk && collect_dense_)
	{
		spill();
		dense_.spillFar(pose.pose.translation().head<2>(),
		                o_.dense_max_range_m + o_.dense_tile_m, spill_);
	}
	prev_ = pose;
	have_prev_ = true;
	scans_++;
	collect_s_ += threadCpuSeconds() - cpu0;
}

void RunCollector::transformDense(const std::function<void(DensePoint&)>& move)
{
	worker_.flush();
	dense_.transformPoints(move);
}

size_t RunCollector::keyframeBytes() const
{
	worker_.flush();
	size_t n = core::vectorBytes(keyframes_);
	for (const auto& k : keyframes_) n += core::vectorBytes(k.points);
	return n;
}

void RunCollector::addGnss(const mrpt::obs::CObservation& obs)
{
	const auto* gps = dynamic_cast<const mrpt::obs::CObservationGPS*>(&obs);
	if (!gps || !gps->has_GGA_datum()) return;
	const auto& f =
	    gps->getMsgByClass<mrpt::obs::gnss::Message_NMEA_GGA>().fields;
	GnssEpoch e;
	e.t_s = mrpt::Clock::toDouble(obs.timestamp);
	e.quality = f.fix_quality;
	e.lat_deg = f.latitude_degrees;
	e.lon_deg = f.longitude_degrees;
	e.alt_m = f.altitude_meters;
	gnss_.push_back(e);
}

}  // namespace forest_slam::outputs
