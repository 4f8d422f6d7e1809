#include <forest_slam/core/log.h>
#include <forest_slam/core/memory.h>
#include <forest_slam/core/scan_points.h>
#include <forest_slam/ingest/velodyne.h>
#include <forest_slam/pipeline/mapping_pipeline.h>

#include <mrpt/obs/CObservationGPS.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/obs/CObservationVelodyneScan.h>
#include <mrpt/system/datetime.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <stdexcept>
#include <string>

namespace forest_slam::pipeline
{
namespace
{
std::string fixed(double v, int decimals)
{
	char buf[64];
	std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
	return buf;
}
}  // namespace

std::string MappingPipeline::when(double t_s) const
{
	std::string out = "t=" + fixed(t_s, 3) + " s";
	if (stats_.scans_in > 0)
		out += " (" + fixed(t_s - stats_.first_stamp_s, 2) + " s into the run)";
	return out;
}

MappingPipeline::MappingPipeline(const MappingConfig& cfg,
                                 std::optional<core::Trajectory> poses)
    : cfg_(cfg),
      poses_(std::move(poses)),
      map_(cfg.forest_map),
      gnss_check_(cfg.pipeline.gnss_max_speed_mps,
                  cfg.pipeline.gnss_jump_tolerance_m),
      imu_buffer_(cfg.odometry.imu),
      outputs_(cfg.outputs, cfg.pipeline.min_range_m, cfg.pipeline.max_range_m)
{
	if (cfg_.pipeline.poseSource() == PoseSource::Trajectory)
	{
		if (!poses_ || poses_->size() < 2)
			throw std::invalid_argument(
			    "[pipeline] pose_source=trajectory needs a trajectory with at "
			    "least 2 poses (forest-slam map --poses FILE.tum)");
	}
	if (cfg_.trees.layer_enabled)
		tree_layer_ = std::make_unique<trees::TreeLayer>(
		    cfg_.trees, cfg_.forest_map.submap_size_m,
		    cfg_.trees.detectDuringRun(/*live_input=*/false));
	initBackEnd();
}

MappingPipeline::~MappingPipeline()
{
	try
	{
		if (odometry_) odometry_->flushMap();
	}
	catch (const std::exception& e)
	{
		// A failed job was already reported by the call that rethrew it,
		// unless the pipeline is going away on another error.
		FS_LOG_DEBUG("map worker error at shutdown: " << e.what());
	}
}

bool MappingPipeline::reachedScanLimit() const
{
	return cfg_.pipeline.max_scans > 0 &&
	       stats_.scans_mapped >= cfg_.pipeline.max_scans;
}

void MappingPipeline::process(const mrpt::obs::CObservation::Ptr& obs)
{
	if (!obs) return;
	stats_.observations++;
	const auto& label = obs->sensorLabel;
	const auto& o = cfg_.pipeline;
	if (label == o.lidar_label)
	{
		if (light_scans_ && processLightScan(*obs)) return;
		if (auto rot =
		        std::dynamic_pointer_cast<mrpt::obs::CObservationRotatingScan>(
		            obs))
			processScan(*rot);
		else if (auto vel = std::dynamic_pointer_cast<
		             mrpt::obs::CObservationVelodyneScan>(obs))
		{
			// Our decoder, not MRPT 2.5.8's fromVelodyne(), which drops half
			// of the returns (see doc/ingest.md).
			mrpt::obs::CObservationRotatingScan converted;
			try
			{
				ingest::velodyneToRotatingScan(*vel, converted);
			}
			catch (const std::exception& e)
			{
				stats_.scans_in++;
				stats_.scans_unreadable++;
				core::logOnce(core::LogLevel::Warn, "velodyne-unreadable",
				              "Velodyne scan " +
				                  std::to_string(stats_.scans_in - 1) +
				                  " cannot be decoded: " + e.what() +
				                  " (skipped; further such scans counted)");
				return;
			}
			processScan(converted);
		}
		else
		{
			stats_.other++;
			core::logOnce(
			    core::LogLevel::Warn,
			    std::string("lidar-type:") + obs->GetRuntimeClass()->className,
			    "observations labelled '" + label + "' of type " +
			        obs->GetRuntimeClass()->className +
			        " are not a rotating lidar scan; ignored");
		}
	}
	else if (label == o.imu_label &&
	         std::dynamic_pointer_cast<mrpt::obs::CObservationIMU>(obs))
	{
		stats_.imu++;
		const double t = mrpt::Clock::toDouble(obs->timestamp);
		if (std::isfinite(t))
			if (const double gap = imu_gaps_.observe(t); gap > 0)
			{
				stats_.imu_gaps++;
				core::logOnce(core::LogLevel::Warn, "imu-gap",
				              "IMU gap: no sample for " + fixed(gap, 2) +
				                  " s before " + when(t) +
				                  "; scans in it go on with the motion model "
				                  "(further gaps counted as imu_gaps)");
			}
		if (!static_pose_) accumulateGravity(*obs);
		if (cfg_.pipeline.poseSource() == PoseSource::Odometry &&
		    cfg_.odometry.odometry.use_imu)
		{
			addImuSample(*obs);
			drainPending(false);
		}
	}
	else if (label == o.gnss_label &&
	         std::dynamic_pointer_cast<mrpt::obs::CObservationGPS>(obs))
	{
		stats_.gnss++;
		checkGnss(*obs);  // a jumping fix reaches neither outputs nor back-end
	}
	else
	{
		stats_.other++;
		core::logOnce(core::LogLevel::Info, "label:" + label,
		              "observations with sensor label '" + label + "' (" +
		                  obs->GetRuntimeClass()->className +
		                  ") are not used by this configuration");
	}
}

void MappingPipeline::checkGnss(const mrpt::obs::CObservation& obs)
{
	const auto& gps = dynamic_cast<const mrpt::obs::CObservationGPS&>(obs);
	if (gps.has_GGA_datum())
	{
		const auto& f =
		    gps.getMsgByClass<mrpt::obs::gnss::Message_NMEA_GGA>().fields;
		const double t = mrpt::Clock::toDouble(obs.timestamp);
		double d = 0;
		if (f.fix_quality > 0 && std::isfinite(t))
		{
			const auto v = gnss_check_.observe(t, f.latitude_degrees,
			                                   f.longitude_degrees, d);
			if (v == GnssJumpCheck::Verdict::Jump)
			{
				stats_.gnss_rejected++;
				core::logOnce(core::LogLevel::Warn, "gnss-jump",
				              "GNSS fix at " + when(t) + " jumped " +
				                  fixed(d, 1) +
				                  " m from the last accepted fix: rejected "
				                  "(further such fixes counted as "
				                  "gnss_rejected)");
				return;
			}
			if (v == GnssJumpCheck::Verdict::Reanchored)
				FS_LOG_WARN("GNSS fixes stayed " << fixed(d, 1)
				                                 << " m away since the jump: "
				                                    "accepted again from "
				                                 << when(t));
		}
	}
	outputs_.addGnss(obs);
	backEndGnss(obs);
}

void MappingPipeline::accumulateGravity(const mrpt::obs::CObservation& o)
{
	const auto& imu = dynamic_cast<const mrpt::obs::CObservationIMU&>(o);
	using mrpt::obs::IMU_X_ACC;
	using mrpt::obs::IMU_Y_ACC;
	using mrpt::obs::IMU_Z_ACC;
	if (!imu.has(IMU_X_ACC) || !imu.has(IMU_Y_ACC) || !imu.has(IMU_Z_ACC))
		return;
	const Eigen::Vector3d a(imu.get(IMU_X_ACC), imu.get(IMU_Y_ACC),
	                        imu.get(IMU_Z_ACC));
	if (!a.allFinite() || a.norm() < 5.0 || a.norm() > 15.0)
		return;  // not at rest
	mrpt::poses::CPose3D imu_on_vehicle;
	imu.getSensorPose(imu_on_vehicle);
	gravity_sum_vehicle_ += imu_on_vehicle.getRotationMatrix().asEigen() * a;
	gravity_samples_++;
}

void MappingPipeline::addImuSample(const mrpt::obs::CObservation& o)
{
	const auto& imu = dynamic_cast<const mrpt::obs::CObservationIMU&>(o);
	using namespace mrpt::obs;
	if (!imu.has(IMU_X_ACC) || !imu.has(IMU_Y_ACC) || !imu.has(IMU_Z_ACC) ||
	    !imu.has(IMU_WX) || !imu.has(IMU_WY) || !imu.has(IMU_WZ))
	{
		core::logOnce(
		    core::LogLevel::Warn, "imu-fields",
		    "IMU observations without accelerations and angular rates: not "
		    "used by the odometry");
		return;
	}
	mrpt::poses::CPose3D imu_on_vehicle;
	imu.getSensorPose(imu_on_vehicle);
	const Eigen::Matrix3d R = imu_on_vehicle.getRotationMatrix().asEigen();
	const Eigen::Vector3d w(imu.get(IMU_WX), imu.get(IMU_WY), imu.get(IMU_WZ));
	const Eigen::Vector3d a(imu.get(IMU_X_ACC), imu.get(IMU_Y_ACC),
	                        imu.get(IMU_Z_ACC));
	const double t = mrpt::Clock::toDouble(imu.timestamp);
	if (!imu_buffer_.add(t, R * w, R * a))
	{
		stats_.imu_rejected++;
		// Two keys: a non-finite sample and a stamp going backwards are
		// different faults and each is named once.
		const bool finite = std::isfinite(t) && w.allFinite() && a.allFinite();
		if (finite)
			core::logOnce(core::LogLevel::Warn, "imu-time-order",
			              "IMU sample at " + when(t) +
			                  " is not after the previous sample (t=" +
			                  fixed(imu_buffer_.latestTime(), 3) +
			                  " s): ignored (further such samples counted "
			                  "as imu_rejected)");
		else
			core::logOnce(core::LogLevel::Warn, "imu-nonfinite",
			              "IMU sample at " + when(t) +
			                  " has a non-finite time, rate or "
			                  "acceleration: ignored (further such samples "
			                  "counted as imu_rejected)");
	}
}

void MappingPipeline::drainPending(bool all)
{
	// A scan waits for the IMU samples of its sweep; if the IMU lags more
	// than max_pending scans (or stalls) it goes on without them.
	constexpr size_t max_pending = 8;
	while (!pending_.empty() && !reachedScanLimit())
	{
		auto& s = pending_.front();
		const bool covered =
		    imu_buffer_.latestTime() >= s.pts.stamp_s + s.pts.sweep_s;
		if (!all && !covered && pending_.size() <= max_pending &&
		    stats_.imu > 0)
			break;
		runOdometry(s);
		pending_.pop_front();
	}
	if (!pending_.empty() && reachedScanLimit()) pending_.clear();
}

const map::CForestMap& MappingPipeline::forestMap() const
{
	if (odometry_) odometry_->flushMap();
	return map_;
}

const trees::TreeLayer* MappingPipeline::treeLayer() const
{
	if (odometry_) odometry_->flushMap();
	return tree_layer_.get();
}

void MappingPipeline::finish()
{
	drainPending(true);
	completeTreeMerge();  // an in-run merge of the tree layer's passes
	if (odometry_) odometry_->flushMap();  // the outputs read the CForestMap
	// The maps and the tree layer's points follow the corrected trajectory
	// first, then the layer detects the columns not done yet and those
	// whose passes the correction moved apart.
	finishBackEnd();
	// The end-of-run detection frees its column buffers once each, on two
	// threads: with the heap kept for the scans' sake (core/memory.h)
	// they stayed in the arenas, and the 60-minute run peaked 1493 -> 1660
	// MB there. From here on the heaps' free tops go back at once.
	core::setHeapKeptFree(core::kHeapKeptAtTheEnd);
	core::releaseFreedHeap();
	finishTreeLayer();
}

Eigen::Matrix3d MappingPipeline::levelledOrientation(
    const Eigen::Vector3d& up_vehicle, const Eigen::Matrix3d& lidar_on_vehicle)
{
	const Eigen::Matrix3d R_level =
	    Eigen::Quaterniond::FromTwoVectors(up_vehicle.normalized(),
	                                       Eigen::Vector3d::UnitZ())
	        .toRotationMatrix();
	const Eigen::Matrix3d R = R_level * lidar_on_vehicle;
	// Heading of the lidar x axis projected on the horizontal plane.
	const double yaw = std::atan2(R(1, 0), R(0, 0));
	return Eigen::AngleAxisd(-yaw, Eigen::Vector3d::UnitZ())
	           .toRotationMatrix() *
	       R;
}

Eigen::Isometry3d MappingPipeline::staticLidarPose(
    const mrpt::poses::CPose3D& lidar_on_vehicle)
{
	if (!static_pose_)
	{
		Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
		if (gravity_samples_ > 0)
		{
			T.linear() = levelledOrientation(
			    gravity_sum_vehicle_ / static_cast<double>(gravity_samples_),
			    lidar_on_vehicle.getRotationMatrix().asEigen());
			FS_LOG_INFO("static pose: map frame levelled with gravity from "
			            << gravity_samples_ << " IMU samples");
		}
		else
			core::logOnce(core::LogLevel::Warn, "static-no-imu",
			              "static pose source without IMU samples before the "
			              "first scan: the map frame is the first lidar frame "
			              "(not levelled)");
		static_pose_ = T;
	}
	return *static_pose_;
}

void MappingPipeline::mapWithOdometry(
    const mrpt::obs::CObservationRotatingScan& scan, core::ScanPoints& pts)
{
	const auto& po = cfg_.pipeline;
	auto& v = pts.points;
	v.erase(std::remove_if(v.begin(), v.end(),
	                       [&](const core::ScanPoint& p)
	                       {
		                       return !(p.range_m >= po.min_range_m &&
		                                p.range_m <= po.max_range_m) ||
		                              !std::isfinite(p.x) ||
		                              !std::isfinite(p.y) ||
		                              !std::isfinite(p.z);
	                       }),
	        v.end());
	if (v.empty())
	{
		stats_.scans_empty++;
		core::logOnce(core::LogLevel::Warn, "scan-empty",
		              "lidar scan at " + when(pts.stamp_s) +
		                  " has no valid return: skipped (further such scans "
		                  "counted as scans_empty)");
		return;
	}
	pending_.push_back({std::move(pts), scan.sensorPose});
	drainPending(false);
}

void MappingPipeline::runOdometry(PendingScan& s)
{
	if (!odometry_)
	{
		odometry_ =
		    std::make_unique<odometry::LidarOdometry>(cfg_.odometry, map_);
		// The map frame: levelled with the IMU attitude filter at the first
		// scan (mean of its first samples) when there is one, else with the
		// gravity seen before the first scan.
		const std::optional<Eigen::Vector3d> up_body =
		    cfg_.odometry.odometry.use_imu
		        ? imu_buffer_.upAt(s.pts.stamp_s, Eigen::Matrix3d::Identity())
		        : std::nullopt;
		if (up_body)
		{
			Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
			T.linear() = levelledOrientation(
			    *up_body, s.sensor_pose.getRotationMatrix().asEigen());
			static_pose_ = T;
			odometry_->setInitialPose(T);
		}
		else
			odometry_->setInitialPose(staticLidarPose(s.sensor_pose));
		if (cfg_.odometry.odometry.use_imu)
			odometry_->setImu(&imu_buffer_,
			                  s.sensor_pose.getRotationMatrix().asEigen());
	}
	auto step = odometry_->processScan(s.pts);
	if (backend_)
	{
		const auto t0 = std::chrono::steady_clock::now();
		backEndScan(s, step.pose);
		stats_.backend_ms.push_back(std::chrono::duration<double, std::milli>(
		                                std::chrono::steady_clock::now() - t0)
		                                .count());
	}
	imu_buffer_.pruneBefore(s.pts.stamp_s - 1.0);
	trajectory_.push_back(step.pose);
	outputs_.addScan(s.pts, step.pose, odometry_->lastDeskewed(),
	                 &odometry_->groundLattice());
	stats_.scans_mapped++;
	stats_.scans_degenerate += step.degenerate;
	stats_.scans_unregistered +=
	    (!step.registered && odometry_->scansProcessed() > 1);
	stats_.scans_imu += step.imu_used;
	stats_.stage_ms.push_back(step.timing);
	feedTreeLayerOdometry(trajectory_.back().pose);
}

bool MappingPipeline::lidarPoseAt(double t_s, Eigen::Isometry3d& out) const
{
	if (cfg_.pipeline.poseSource() == PoseSource::Static)
	{
		out = static_pose_ ? *static_pose_ : Eigen::Isometry3d::Identity();
		return true;
	}
	return core::interpolatePose(*poses_, t_s, out, 1e-3);
}

bool MappingPipeline::dropNonFinite(core::ScanPoints& pts)
{
	auto& v = pts.points;
	const size_t n = v.size();
	v.erase(std::remove_if(v.begin(), v.end(),
	                       [](const core::ScanPoint& p)
	                       {
		                       return !std::isfinite(p.x) ||
		                              !std::isfinite(p.y) ||
		                              !std::isfinite(p.z) ||
		                              !std::isfinite(p.t_s);
	                       }),
	        v.end());
	const size_t bad = n - v.size();
	if (bad == 0) return true;
	stats_.points_nonfinite += bad;
	// Corrupt geometry, not an empty view: reported under its own name.
	core::logOnce(core::LogLevel::Warn, "scan-nonfinite",
	              "lidar scan at " + when(pts.stamp_s) + " has " +
	                  std::to_string(bad) + " of " + std::to_string(n) +
	                  " points not finite (NaN/inf): dropped (further such "
	                  "points counted as points_nonfinite)");
	if (!v.empty()) return true;
	stats_.scans_unreadable++;
	return false;
}

void MappingPipeline::processScan(
    const mrpt::obs::CObservationRotatingScan& scan)
{
	stats_.scans_in++;
	const double stamp = mrpt::Clock::toDouble(scan.timestamp);
	if (stats_.scans_in == 1) stats_.first_stamp_s = stamp;
	if (have_last_scan_ && stamp == last_scan_stamp_s_)
	{
		stats_.scans_out_of_order++;
		stats_.scans_duplicate++;
		core::logOnce(core::LogLevel::Warn, "scan-duplicate",
		              "lidar scan " + std::to_string(stats_.scans_in - 1) +
		                  " at " + when(stamp) +
		                  " repeats the previous scan's time (a duplicate): "
		                  "skipped (further duplicates counted as "
		                  "scans_duplicate)");
		return;
	}
	if (!std::isfinite(stamp) ||
	    (have_last_scan_ && stamp <= last_scan_stamp_s_))
	{
		stats_.scans_out_of_order++;
		core::logOnce(core::LogLevel::Warn, "scan-time-order",
		              "lidar scan " + std::to_string(stats_.scans_in - 1) +
		                  " at " + when(stamp) +
		                  " is not after the previous scan (" +
		                  std::to_string(last_scan_stamp_s_) +
		                  " s): skipped (further such scans counted silently)");
		return;
	}
	have_last_scan_ = true;
	last_scan_stamp_s_ = stamp;
	stats_.last_stamp_s = stamp;
	if (const double gap = scan_gaps_.observe(stamp); gap > 0)
	{
		stats_.lidar_gaps++;
		core::logOnce(core::LogLevel::Warn, "lidar-gap",
		              "lidar gap: no scan for " + fixed(gap, 2) + " s before " +
		                  when(stamp) +
		                  "; the motion model bridges it (further gaps "
		                  "counted as lidar_gaps)");
	}

	core::ScanPoints pts;
	try
	{
		pts = core::unpackRotatingScan(scan);
	}
	catch (const std::exception& e)
	{
		stats_.scans_unreadable++;
		core::logOnce(core::LogLevel::Warn, "scan-unreadable",
		              "lidar scan " + std::to_string(stats_.scans_in - 1) +
		                  " cannot be decoded: " + e.what() + " (skipped)");
		return;
	}
	stats_.points_in += pts.points.size();
	if (!dropNonFinite(pts)) return;
	if (cfg_.pipeline.poseSource() == PoseSource::Odometry)
	{
		mapWithOdometry(scan, pts);
		return;
	}

	if (cfg_.pipeline.poseSource() == PoseSource::Static)
		staticLidarPose(scan.sensorPose);
	Eigen::Isometry3d scan_pose;
	if (!lidarPoseAt(stamp, scan_pose) ||
	    (cfg_.pipeline.deskew && !lidarPoseAt(stamp + pts.sweep_s, scan_pose)))
	{
		stats_.scans_outside_poses++;
		core::logOnce(core::LogLevel::Warn, "scan-no-pose",
		              "lidar scan at t=" + std::to_string(stamp) +
		                  " s is outside the --poses trajectory: skipped");
		return;
	}
	lidarPoseAt(stamp, scan_pose);

	// Per ring, in firing order, with the range gate applied.
	const auto& po = cfg_.pipeline;
	std::vector<std::vector<const core::ScanPoint*>> rings(scan.rowCount);
	for (const auto& p : pts.points)
		if (p.range_m >= po.min_range_m && p.range_m <= po.max_range_m &&
		    std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z))
			rings[p.ring].push_back(&p);

	// Deskew poses per firing column, computed once and shared by all rings.
	std::vector<Eigen::Isometry3f> column_pose(scan.columnCount);
	std::vector<uint8_t> column_done(scan.columnCount, 0);
	auto poseOfColumn =
	    [&](const core::ScanPoint& p) -> const Eigen::Isometry3f&
	{
		if (!column_done[p.column])
		{
			Eigen::Isometry3d T = scan_pose;
			if (po.deskew) lidarPoseAt(stamp + p.t_s, T);
			column_pose[p.column] = T.cast<float>();
			column_done[p.column] = 1;
		}
		return column_pose[p.column];
	};

	std::vector<Eigen::Vector3f> edge_map, planar_map, ring_xyz;
	const auto& mo = cfg_.forest_map;
	size_t valid = 0;
	for (const auto& ring : rings)
	{
		ring_xyz.clear();
		for (const auto* p : ring) ring_xyz.emplace_back(p->x, p->y, p->z);
		valid += ring.size();
		// Smoothness on the raw ring order (sensor frame); each point then
		// moves with the pose at its own firing time (deskew).
		const auto edge = map::smoothnessEdgeFlags(
		    ring_xyz, mo.smoothness_half_window, mo.edge_smoothness_threshold);
		for (size_t i = 0; i < ring.size(); i++)
			(edge[i] ? edge_map : planar_map)
			    .push_back(poseOfColumn(*ring[i]) * ring_xyz[i]);
	}
	if (valid == 0)
	{
		stats_.scans_empty++;
		core::logOnce(core::LogLevel::Warn, "scan-empty",
		              "lidar scan at " + when(stamp) +
		                  " has no valid return: skipped (further such scans "
		                  "counted as scans_empty)");
		return;
	}
	map_.insertFeatures(edge_map, planar_map);
	trajectory_.push_back({stamp, scan_pose});
	feedTreeLayer(edge_map, planar_map, scan_pose.translation());
	outputs_.addScan(pts, trajectory_.back(),
	                 [&](double t, Eigen::Isometry3d& T)
	                 { return po.deskew && lidarPoseAt(t, T); });
	stats_.scans_mapped++;
}

}  // namespace forest_slam::pipeline
