// The back-end's hook into the mapping pipeline (doc/backend.md): every
// odometry pose may make a keyframe for loop::BackEnd; the back-end's
// corrections are applied when keyframe k + latency_keyframes is made (the
// same scans in every run, whatever the thread timing), to the odometry's
// pose and local map so that drift does not re-accumulate; GNSS fixes are
// attached to the keyframe before them; at the end every scan pose follows
// its keyframe and the tree layer and the output keyframes follow.
#include <forest_slam/core/log.h>
#include <forest_slam/core/memory.h>
#include <forest_slam/core/time_index.h>
#include <forest_slam/odometry/lidar_odometry.h>
#include <forest_slam/pipeline/mapping_pipeline.h>

#include <mrpt/obs/CObservationGPS.h>
#include <mrpt/system/datetime.h>
#include <GeographicLib/LocalCartesian.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <unordered_map>

namespace forest_slam::pipeline
{
struct MappingPipeline::GnssOrigin
{
	GeographicLib::LocalCartesian enu;
};

struct MappingPipeline::TreeMerge
{
	/** Correction of every scan mapped at the merge's start, per merge
	 * version of the columns to move (TreeLayer::AtTime). */
	std::map<uint32_t, std::vector<Eigen::Isometry3f,
	                               Eigen::aligned_allocator<Eigen::Isometry3f>>>
	    C;
	std::vector<trees::ColumnKey> keys;  ///< the columns to move (all: {})
	uint32_t version = 0;                ///< this merge's number
	core::TimeIndex clock{std::vector<double>{0.0}};
	std::vector<Eigen::Vector2d> xy;  ///< their positions as mapped
	// On the map worker only:
	std::optional<trees::TreeLayer::CorrectionSteps> steps;
	/** Voxels the steps may still move (each step adds its share; a big
	 * column takes it below zero). */
	int64_t credit = 0;
	size_t step_jobs = 0;  ///< steps that moved columns
	double work_s = 0;     ///< their wall time
	std::chrono::steady_clock::time_point started;
	double rss0_mb = 0;
	/** Set by the last step; read by the mapping thread, which stops
	 * queueing steps (one too many is a no-op). */
	std::atomic<bool> done{false};
};

void MappingPipeline::initBackEnd()
{
	if (!cfg_.loop.enabled) return;
	if (cfg_.pipeline.poseSource() != PoseSource::Odometry)
	{
		core::logOnce(core::LogLevel::Warn, "loop-pose-source",
		              "[loop] enabled needs [pipeline] pose_source=odometry; "
		              "the back-end is off for this run");
		return;
	}
	// Keyframe clouds of a long run on disk, like the dense map's tiles.
	std::shared_ptr<core::SpillFile> spill;
	if (cfg_.outputs.spill_to_disk)
		spill = std::make_shared<core::SpillFile>(cfg_.outputs.spill_dir);
	backend_ = std::make_unique<loop::BackEnd>(cfg_.loop, true, spill);
}

namespace
{
/** Stem-band voxels moved per mapped scan, on average, by an in-run merge
 * of the tree layer's passes: whole columns, so a step with a big one is
 * followed by steps that do nothing until the credit is paid back (tens of
 * ms per scan on the map thread; the 58-minute run's columns hold up to a
 * few million voxels). */
constexpr size_t kTreeMergeStepVoxels = 150000;

double angleDeg(const Eigen::Matrix3d& R)
{
	return Eigen::AngleAxisd(R).angle() * 180.0 / M_PI;
}
}  // namespace

void MappingPipeline::backEndScan(const PendingScan& s, core::StampedPose& pose)
{
	if (!backend_) return;
	// An in-run merge of the tree layer's passes goes on, a step after the
	// insertion of each scan.
	if (tree_merge_ && tree_merge_->done)
		tree_merge_.reset();
	else if (tree_merge_)
		stepTreeMerge(kTreeMergeStepVoxels);
	const auto& lo = cfg_.loop;
	if (last_scan_pose_)
		travelled_m_ +=
		    (pose.pose.translation() - last_scan_pose_->pose.translation())
		        .norm();
	// Test bench: a yaw and height error every inject_every_m, about the
	// sensor, as a drifting odometry would make (the local map moves too,
	// so the registration keeps it).
	if (lo.injectsDrift() && travelled_m_ >= next_inject_m_)
	{
		if (next_inject_m_ > 0)
		{
			const double d = lo.inject_every_m;
			Eigen::Isometry3d D = Eigen::Isometry3d::Identity();
			D.linear() =
			    Eigen::AngleAxisd(lo.inject_yaw_deg_per_m * d * M_PI / 180,
			                      Eigen::Vector3d::UnitZ())
			        .toRotationMatrix();
			D.translation().z() = lo.inject_z_m_per_m * d;
			Eigen::Isometry3d P = Eigen::Isometry3d::Identity();
			P.translation() = pose.pose.translation();
			const Eigen::Isometry3d C = P * D * P.inverse();
			odometry_->applyCorrection(C);
			pose.pose = C * pose.pose;
		}
		next_inject_m_ += lo.inject_every_m;
	}

	// Keyframe?
	const bool first = kf_pose_.empty();
	bool make = first;
	if (!first)
	{
		const Eigen::Isometry3d d = kf_pose_.back().inverse() * pose.pose;
		make = d.translation().norm() >= lo.keyframe_distance_m ||
		       angleDeg(d.linear()) >= lo.keyframe_angle_deg;
	}
	if (make)
	{
		loop::Keyframe kf;
		kf.stamp_s = pose.t_s;
		kf.travelled_m = travelled_m_;
		kf.odom_edge =
		    first ? pose.pose : kf_pose_.back().inverse() * pose.pose;
		// Deskewed cloud in the keyframe frame: the sweep's motion from the
		// last scan (and the IMU rotation when there is one).
		odometry::SweepMotion m;
		m.t0_s = s.pts.stamp_s;
		m.sweep_s = s.pts.sweep_s;
		if (last_scan_pose_ && pose.t_s > last_scan_pose_->t_s)
			m.end = core::interpolateIsometry(
			    Eigen::Isometry3d::Identity(),
			    last_scan_pose_->pose.inverse() * pose.pose,
			    s.pts.sweep_s / (pose.t_s - last_scan_pose_->t_s));
		if (cfg_.odometry.odometry.use_imu &&
		    imu_buffer_.covers(s.pts.stamp_s, s.pts.stamp_s + s.pts.sweep_s))
		{
			m.imu = &imu_buffer_;
			m.R_body_lidar = s.sensor_pose.getRotationMatrix().asEigen();
			kf.up = imu_buffer_.upAt(pose.t_s, m.R_body_lidar);
		}
		std::vector<Eigen::Vector3f> pts;
		for (const auto& p : odometry::deskewScan(s.pts, m))
			pts.push_back(p.xyz);
		kf.cloud =
		    loop::voxelFilter(pts, lo.cloud_voxel_m, lo.cloud_max_range_m);
		const size_t id = backend_->addKeyframe(std::move(kf));
		kf_pose_.push_back(pose.pose);
		const size_t lat = static_cast<size_t>(lo.latency_keyframes);
		loop::Poses X;
		if (id >= lat && backend_->resultAt(id - lat, X))
		{
			// Correction of the map frame at the newest optimised
			// keyframe; the keyframes made since move rigidly with it.
			const size_t k = X.size() - 1;
			const Eigen::Isometry3d C = X[k] * kf_pose_[k].inverse();
			odometry_->applyCorrection(C);
			// The scans mapped so far (this one included: the odometry
			// queued it before the correction) stay in the old segment of
			// the CForestMap, unless the correction is below its voxels.
			const double moves_m =
			    C.translation().norm() + Eigen::AngleAxisd(C.linear()).angle() *
			                                 cfg_.forest_map.max_insert_range_m;
			if (moves_m > 0.5 * cfg_.forest_map.edge_voxel_m)
			{
				odometry_->flushMap();
				if (map_.segmentCount() >= 2 || tree_layer_)
				{
					const core::Trajectory now = currentEstimate(X, C);
					mergeForestMapSegments(now);
					mergeTreeLayerPasses(now, X, C);
				}
				// On the map worker, after the merge queued above (if one
				// was): the segment starts after this scan's insertion.
				odometry_->runOnMap(
				    [this, first = trajectory_.size() + 1](map::CForestMap& m)
				    {
					    const size_t n = m.segmentCount();
					    m.startSegment();
					    if (m.segmentCount() > n)
						    map_segment_first_scan_.push_back(first);
				    });
			}
			// The tree layer: this scan and the next ones are a new pass
			// (its job is queued after this one), unless the correction
			// is below half a stem-band voxel.
			const double stem_moves_m =
			    C.translation().norm() + Eigen::AngleAxisd(C.linear()).angle() *
			                                 cfg_.trees.layer_max_range_m;
			if (tree_layer_ && stem_moves_m > 0.5 * cfg_.trees.layer_voxel_m)
				odometry_->runOnMap([this](map::CForestMap&)
				                    { tree_layer_->startPass(); });
			for (auto& T : kf_pose_) T = C * T;
			pose.pose = C * pose.pose;
			if (last_scan_pose_)
				last_scan_pose_->pose = C * last_scan_pose_->pose;
			FS_LOG_DEBUG("back-end correction at keyframe "
			             << id << ": " << C.translation().norm() << " m, "
			             << angleDeg(C.linear()) << " deg");
		}
	}
	anchors_.push_back(
	    {kf_pose_.size() - 1, kf_pose_.back().inverse() * pose.pose});

	// GNSS fixes taken before this scan: position at the fix time
	// interpolated between the last two scan poses, attached to the newest
	// keyframe.
	while (!gnss_pending_.empty() && gnss_pending_.front().t_s <= pose.t_s)
	{
		const auto f = gnss_pending_.front();
		gnss_pending_.pop_front();
		if (!last_scan_pose_ || f.t_s < last_scan_pose_->t_s) continue;
		const double a = (f.t_s - last_scan_pose_->t_s) /
		                 std::max(1e-9, pose.t_s - last_scan_pose_->t_s);
		const Eigen::Isometry3d T =
		    core::interpolateIsometry(last_scan_pose_->pose, pose.pose, a);
		const Eigen::Vector3d lever =
		    s.sensor_pose.getRotationMatrix().asEigen().transpose() *
		    (f.antenna_on_vehicle - Eigen::Vector3d(s.sensor_pose.x(),
		                                            s.sensor_pose.y(),
		                                            s.sensor_pose.z()));
		loop::GnssFix g;
		g.stamp_s = f.t_s;
		g.keyframe = kf_pose_.size() - 1;
		g.antenna_in_keyframe = kf_pose_.back().inverse() * (T * lever);
		g.enu = f.enu;
		g.sigma = f.sigma;
		backend_->addGnss(g);
	}
	last_scan_pose_ = pose;
}

void MappingPipeline::backEndGnss(const mrpt::obs::CObservation& obs)
{
	if (!backend_ || !cfg_.loop.gnss_enabled) return;
	const auto& gps = dynamic_cast<const mrpt::obs::CObservationGPS&>(obs);
	if (!gps.has_GGA_datum()) return;
	const auto& gga =
	    gps.getMsgByClass<mrpt::obs::gnss::Message_NMEA_GGA>().fields;
	if (gga.fix_quality < static_cast<unsigned>(cfg_.loop.gnss_min_quality))
		return;
	// Per-axis sigmas from BESTPOS (forest-sim, bag2rawlog from NavSatFix
	// covariances); a fix without them is not used: its weight is unknown.
	using mrpt::obs::gnss::Message_NV_OEM6_BESTPOS;
	if (!gps.hasMsgClass<Message_NV_OEM6_BESTPOS>())
	{
		core::logOnce(core::LogLevel::Warn, "gnss-no-sigma",
		              "GNSS observations without per-axis sigmas (BESTPOS): "
		              "not used by the back-end");
		return;
	}
	const auto& b = gps.getMsgByClass<Message_NV_OEM6_BESTPOS>().fields;
	const Eigen::Vector3d sigma(b.lon_sigma, b.lat_sigma, b.hgt_sigma);
	if (!(sigma.minCoeff() > 0) ||
	    sigma.head<2>().maxCoeff() > cfg_.loop.gnss_max_sigma_m)
		return;
	if (!std::isfinite(gga.latitude_degrees) ||
	    !std::isfinite(gga.longitude_degrees))
		return;
	if (!gnss_origin_)
	{
		gnss_origin_ = std::make_shared<GnssOrigin>();
		gnss_origin_->enu.Reset(gga.latitude_degrees, gga.longitude_degrees,
		                        gga.altitude_meters);
	}
	PendingFix f;
	f.t_s = mrpt::Clock::toDouble(obs.timestamp);
	gnss_origin_->enu.Forward(gga.latitude_degrees, gga.longitude_degrees,
	                          gga.altitude_meters, f.enu.x(), f.enu.y(),
	                          f.enu.z());
	// Errors under canopy wander (first-order Gauss-Markov, time constant
	// gnss_correlation_s): the fixes within about two time constants are
	// worth one, so each fix's sigma is inflated by sqrt(2 tau / interval).
	// Taken as independent, 800 canopy fixes of the forest-sim robot run
	// bent the loop-closed map by 0.3 m (doc/backend.md).
	const double tau = cfg_.loop.gnss_correlation_s;
	const double dt = last_gnss_fix_s_ < 0 ? 0 : f.t_s - last_gnss_fix_s_;
	last_gnss_fix_s_ = f.t_s;
	f.sigma = sigma;
	if (tau > 0 && dt > 0) f.sigma *= std::sqrt(std::max(1.0, 2 * tau / dt));
	f.antenna_on_vehicle = Eigen::Vector3d(
	    gps.sensorPose.x(), gps.sensorPose.y(), gps.sensorPose.z());
	gnss_pending_.push_back(f);
}

void MappingPipeline::finishBackEnd()
{
	if (!backend_) return;
	backend_->finish();
	const auto X = backend_->poses();
	if (X.size() != kf_pose_.size() || anchors_.size() != trajectory_.size())
		throw std::logic_error("back-end: keyframe/scan bookkeeping mismatch");
	const core::Trajectory mapped = trajectory_;
	for (size_t i = 0; i < trajectory_.size(); i++)
		trajectory_[i].pose = X[anchors_[i].keyframe] * anchors_[i].offset;
	// Output keyframes: their pose is a scan pose.
	const auto& kfs = outputs_.keyframes();
	for (size_t i = 0; i < kfs.size(); i++)
	{
		Eigen::Isometry3d T;
		if (core::interpolatePose(trajectory_, kfs[i].t_s, T, 1e-6))
			outputs_.setKeyframePose(i, T);
	}
	// Dense map, CForestMap and tree layer: unchanged (bit for bit) when
	// nothing was optimised or levelled.
	const bool moved =
	    (backend_->stats().optimisations > 0 || backend_->stats().levelled) &&
	    !mapped.empty();
	if (moved)
	{
		const auto t0 = std::chrono::steady_clock::now();
		const size_t segments = map_.segmentCount();
		correctDenseMap(mapped);
		const auto t1 = std::chrono::steady_clock::now();
		correctForestMap(mapped, trajectory_);
		// The tables freed on the way go back to the system (glibc keeps
		// freed heap otherwise: +280 MB RSS on the handheld run).
		core::releaseFreedHeap();
		const auto t2 = std::chrono::steady_clock::now();
		using S = std::chrono::duration<double>;
		FS_LOG_INFO(
		    "back-end corrections: dense map ("
		    << outputs_.dense().size() << " points) moved in "
		    << S(t1 - t0).count() << " s, CForestMap (" << segments
		    << " segments, " << map_.edgePointCount() + map_.planarPointCount()
		    << " voxels once merged; " << map_merges_
		    << " merges during the run) in " << S(t2 - t1).count() << " s");
	}
	if (tree_layer_ && moved) correctTreeLayer(mapped);
	const auto st = backend_->stats();
	FS_LOG_INFO("back-end: " << st.keyframes << " keyframes, " << st.candidates
	                         << " loop candidates, " << st.closures
	                         << " closures, " << st.optimisations
	                         << " optimisations, GNSS " << st.gnss_fixes
	                         << " fixes (" << st.gnss_outliers << " outliers)");
	if (st.levelled)
		FS_LOG_INFO("back-end: map levelled with gravity by "
		            << st.levelling_deg << " deg (IMU up at "
		            << st.levelling_keyframes << " keyframes, residual RMS "
		            << st.levelling_rms_deg << " deg)");
}

namespace
{
/** Correction of every scan: corrected pose * mapped pose^-1. */
std::vector<Eigen::Isometry3f, Eigen::aligned_allocator<Eigen::Isometry3f>>
scanCorrections(const core::Trajectory& corrected,
                const core::Trajectory& mapped)
{
	std::vector<Eigen::Isometry3f, Eigen::aligned_allocator<Eigen::Isometry3f>>
	    C(mapped.size());
	for (size_t i = 0; i < mapped.size(); i++)
		C[i] = (corrected[i].pose * mapped[i].pose.inverse()).cast<float>();
	return C;
}

std::vector<double> scanTimes(const core::Trajectory& mapped)
{
	std::vector<double> t(mapped.size());
	for (size_t i = 0; i < mapped.size(); i++) t[i] = mapped[i].t_s;
	return t;
}

std::vector<Eigen::Vector2d> scanPositions(const core::Trajectory& mapped)
{
	std::vector<Eigen::Vector2d> xy;
	xy.reserve(mapped.size());
	for (const auto& p : mapped) xy.push_back(p.pose.translation().head<2>());
	return xy;
}

/** The scan that passed nearest (horizontally) to the centre of column k:
 * its correction moves the column's ground cells and trees. */
size_t scanNearestColumn(const std::vector<Eigen::Vector2d>& xy,
                         const trees::ColumnKey& k, double column_m)
{
	const Eigen::Vector2d centre((k.x + 0.5) * column_m,
	                             (k.y + 0.5) * column_m);
	size_t best = 0;
	double bd = 1e300;
	for (size_t i = 0; i < xy.size(); i++)
	{
		const double d = (xy[i] - centre).squaredNorm();
		if (d < bd) bd = d, best = i;
	}
	return best;
}
}  // namespace

core::Trajectory MappingPipeline::treeMapped(const core::Trajectory& as_mapped,
                                             uint32_t version) const
{
	if (version == 0) return as_mapped;
	const auto& e = tree_merge_estimates_.at(version - 1);
	return estimateOf(as_mapped, e.X, e.C, e.scans);
}

void MappingPipeline::correctTreeLayer(const core::Trajectory& as_mapped)
{
	// A column's scans before the in-run merge that last moved it: from
	// where that merge put their voxels.
	std::map<uint32_t, core::Trajectory> mapped;
	for (const auto& k : tree_layer_->columns())
	{
		const uint32_t v = tree_layer_->mergeVersion(k);
		if (!mapped.count(v)) mapped.emplace(v, treeMapped(as_mapped, v));
	}
	// Stem-band voxels move with the correction of the scan at their mean
	// time (the passes were kept apart for this); ground cells and trees
	// with that of the scan that passed nearest to the column's centre.
	std::map<uint32_t, std::vector<Eigen::Isometry3f,
	                               Eigen::aligned_allocator<Eigen::Isometry3f>>>
	    C;
	for (const auto& [v, m] : mapped)
		C.emplace(v, scanCorrections(trajectory_, m));
	const core::TimeIndex clock(scanTimes(as_mapped));
	const auto at_time = [&](uint32_t v, double ts)
	{ return C.at(v)[clock.at(ts)]; };
	const auto xy = scanPositions(as_mapped);
	const auto of_column = [&](const trees::ColumnKey& k)
	{
		const size_t n = scanNearestColumn(xy, k, tree_layer_->columnSize());
		return Eigen::Isometry3d(
		    trajectory_[n].pose *
		    mapped.at(tree_layer_->mergeVersion(k))[n].pose.inverse());
	};
	const auto t0 = std::chrono::steady_clock::now();
	const size_t redetect = tree_layer_->correct(at_time, of_column, map_);
	FS_LOG_INFO(
	    "back-end corrections: tree layer ("
	    << tree_layer_->columns().size() << " columns) moved in "
	    << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
	           .count()
	    << " s; " << redetect
	    << " columns whose passes disagreed are detected again; "
	    << tree_merges_
	    << " merges of the passes during the run; peak RSS so far "
	    << core::peakRssMb() << " MB");
}

void MappingPipeline::correctDenseMap(const core::Trajectory& mapped)
{
	// Each point moves with the correction of its scan, found from the
	// point's time (the last scan starting at or before it): exact, and
	// nothing was spent on it while mapping.
	const auto C = scanCorrections(trajectory_, mapped);
	const core::TimeIndex clock(scanTimes(mapped));
	const auto& t = clock.times();
	const double t0 = outputs_.dense().timeOrigin();
	size_t k = 0;
	outputs_.transformDense(
	    [&](outputs::DensePoint& p)
	    {
		    const double tp = t0 + p.t_s;
		    if (!(t[k] <= tp && (k + 1 == t.size() || tp < t[k + 1])))
			    k = clock.at(tp);
		    p.xyz = C[k] * p.xyz;
	    });
}

core::Trajectory MappingPipeline::currentEstimate(
    const loop::Poses& X, const Eigen::Isometry3d& C) const
{
	return estimateOf(trajectory_, X, C, trajectory_.size());
}

core::Trajectory MappingPipeline::estimateOf(const core::Trajectory& mapped,
                                             const loop::Poses& X,
                                             const Eigen::Isometry3d& C,
                                             size_t scans) const
{
	// Scans anchored to an optimised keyframe follow it (as at the end of
	// the run), the later ones move with C.
	core::Trajectory now = mapped;
	for (size_t i = 0; i < scans && i < now.size(); i++)
		now[i].pose = anchors_[i].keyframe < X.size()
		                  ? X[anchors_[i].keyframe] * anchors_[i].offset
		                  : C * mapped[i].pose;
	return now;
}

void MappingPipeline::stepTreeMerge(size_t max_voxels)
{
	if (!tree_merge_ || tree_merge_->done) return;
	odometry_->runOnMap(
	    [this, m = tree_merge_, max_voxels](map::CForestMap& fm)
	    {
		    if (m->done) return;
		    if (!m->steps)
		    {
			    m->started = std::chrono::steady_clock::now();
			    m->rss0_mb = core::currentRssMb();
			    m->steps =
			        tree_layer_->beginCorrection(true, m->keys, m->version);
		    }
		    const bool all = max_voxels == std::numeric_limits<size_t>::max();
		    if (!all)
		    {
			    m->credit += int64_t(max_voxels);
			    if (m->credit <= 0) return;  // a big column paid back
		    }
		    const auto at_time = [&](uint32_t v, double ts)
		    { return m->C.at(v)[m->clock.at(ts)]; };
		    const double column_m = tree_layer_->columnSize();
		    const auto of_column = [&](const trees::ColumnKey& k)
		    {
			    return Eigen::Isometry3d(m->C.at(tree_layer_->mergeVersion(
			        k))[scanNearestColumn(m->xy, k, column_m)]
			                                 .cast<double>());
		    };
		    m->step_jobs++;
		    const size_t moved0 = m->steps->moved_voxels;
		    const auto t0 = std::chrono::steady_clock::now();
		    const bool done =
		        tree_layer_->correctStep(*m->steps, at_time, of_column, fm,
		                                 all ? max_voxels : size_t(m->credit));
		    m->credit -= int64_t(m->steps->moved_voxels - moved0);
		    m->work_s += std::chrono::duration<double>(
		                     std::chrono::steady_clock::now() - t0)
		                     .count();
		    if (!done) return;
		    // Rare (a handful an hour): logged with the memory.
		    FS_LOG_INFO("tree layer: passes merged during the run ("
		                << m->steps->keys.size() << " columns, "
		                << m->steps->moved_voxels << " voxels, in "
		                << m->step_jobs << " steps: " << m->work_s
		                << " s of work over "
		                << std::chrono::duration<double>(
		                       std::chrono::steady_clock::now() - m->started)
		                       .count()
		                << " s); RSS " << m->rss0_mb << " -> "
		                << core::currentRssMb() << " MB");
		    m->done = true;
	    });
}

void MappingPipeline::completeTreeMerge()
{
	stepTreeMerge(std::numeric_limits<size_t>::max());
	tree_merge_.reset();  // the queued job holds it
}

void MappingPipeline::mergeTreeLayerPasses(const core::Trajectory& now,
                                           const loop::Poses& X,
                                           const Eigen::Isometry3d& C)
{
	// The map worker is idle (flushed): its counts can be read.
	if (!tree_layer_) return;
	// Both the display and a merge need, per merge version, every scan's
	// correction from where that version put it to `now`, and the scans'
	// positions: made once here, when first needed.
	decltype(TreeMerge::C) corrections;
	const auto correctionsOf = [&](uint32_t v) -> const auto&
	{
		auto it = corrections.find(v);
		if (it == corrections.end())
			it = corrections
			         .emplace(v,
			                  scanCorrections(now, treeMapped(trajectory_, v)))
			         .first;
		return it->second;
	};
	std::vector<Eigen::Vector2d> xy;
	const auto positions = [&]() -> const std::vector<Eigen::Vector2d>&
	{
		if (xy.empty()) xy = scanPositions(trajectory_);
		return xy;
	};
	// Trees during the run: those found so far are shown where this
	// estimate puts them, each column's by the correction (from the
	// estimate its voxels are in) of the scan that passed nearest to its
	// centre, until a merge moves its voxels. Before, they stayed where
	// the last merge had put them, up to a merge's worth of corrections
	// behind the map. (Merging only the columns where the passes piled
	// up, as for a recorded run, was tried: the 58-minute run's
	// corrections fell by 4.5 s of CPU, its store, spilling and detections
	// rose by 10 s: more passes left unmerged.)
	if (tree_layer_->detectsDuringRun())
	{
		std::vector<std::pair<trees::ColumnKey, Eigen::Isometry3d>> shown;
		for (const auto& k : tree_layer_->columns())
		{
			const auto& of_scan = correctionsOf(tree_layer_->mergeVersion(k));
			const size_t n =
			    scanNearestColumn(positions(), k, tree_layer_->columnSize());
			shown.emplace_back(k, of_scan[n].cast<double>());
		}
		odometry_->runOnMap([this, shown = std::move(shown)](map::CForestMap& m)
		                    { tree_layer_->showColumns(shown, m); });
	}
	// A merge still in steps goes on; the next correction looks again.
	// (Flushed, every step queued so far has run: whether it is done is
	// the same in every run.)
	if (tree_merge_ && !tree_merge_->done) return;
	const size_t voxels = tree_layer_->stats().stored_voxels;
	std::vector<trees::ColumnKey> keys;  // empty: every column
	if (tree_layer_->detectsDuringRun())
	{
		// Online, a merge also moves the stems found so far with the
		// corrections: half as many voxels again as at the last merge.
		// Twice as many was tried (2026-12-04): a third fewer voxel moves
		// on the robot run, but the merges' timing decides which stems
		// blur (passes merged at an estimate that later changes), and on
		// the 58-minute run one 56 cm stem read 84 cm.
		if (2 * voxels < 3 * tree_voxels_at_merge_) return;
	}
	else
	{
		// Stems detected at the end: the final correction moves every voxel
		// with its own scan's correction, and a merge during the run only
		// bounds the passes piling up where the path comes back (each lap
		// one more copy of the stems around it). So only the columns where
		// they piled up are merged: stem-band voxels per ground cell (the
		// area seen) grown by half since their last merge, or since they
		// were complete (out of the sensor's reach; the sensor: where the
		// last scan was mapped, the layer's frame;
		// TreeLayer::takePiledUpColumns). By the voxel
		// count alone, the robot run (new ground most of the way) merged 3
		// times, a quarter of the layer's CPU, and each merge froze its
		// passes at an estimate that later closures moved; by the density
		// of the whole layer, twice, every column each time.
		keys = tree_layer_->takePiledUpColumns(
		    1.5, trajectory_.back().pose.translation());
		if (keys.empty()) return;
	}
	auto m = std::make_shared<TreeMerge>();
	m->keys = keys;
	m->version = uint32_t(tree_merge_estimates_.size() + 1);
	// Each column moves from where its own last merge put it.
	for (const auto& k : keys.empty() ? tree_layer_->columns() : keys)
	{
		const uint32_t v = tree_layer_->mergeVersion(k);
		if (!m->C.count(v)) m->C.emplace(v, correctionsOf(v));
	}
	m->clock = core::TimeIndex(scanTimes(trajectory_));
	// Ground cells and trees: the correction of the scan nearest to the
	// column's centre (as in correctTreeLayer).
	m->xy = positions();
	tree_merge_ = m;
	stepTreeMerge(kTreeMergeStepVoxels);
	tree_merge_estimates_.push_back({X, C, now.size()});
	// The estimates no column is in any more (the merge's columns take the
	// new one) are freed.
	std::vector<bool> used(tree_merge_estimates_.size() + 1, false);
	used[m->version] = true;
	for (const auto& k : tree_layer_->columns())
	{
		const bool moved =
		    keys.empty() || std::binary_search(keys.begin(), keys.end(), k);
		if (!moved) used[tree_layer_->mergeVersion(k)] = true;
	}
	for (size_t v = 1; v < used.size(); v++)
		if (!used[v]) tree_merge_estimates_[v - 1] = MergeEstimate();
	// The count after the merge is known only on the worker: the next
	// merge waits for half as many again as before this one.
	tree_voxels_at_merge_ = voxels;
	tree_merges_++;
}

void MappingPipeline::mergeForestMapSegments(const core::Trajectory& now)
{
	// The map worker is idle (flushed): the map can be read here.
	const size_t voxels = map_.edgePointCount() + map_.planarPointCount();
	if (map_.segmentCount() < 2 || 2 * voxels < 3 * map_voxels_at_merge_)
		return;
	const size_t segments = map_.segmentCount();
	// Planned here, moved on the map worker: the odometry goes on meanwhile
	// (0.4–1.3 s per merge on the forest-sim runs, which held the scans of
	// a live run back), and the insertions queue behind the merge.
	auto move = forestMapCorrection(trajectory_, now);
	map_merged_pose_.resize(now.size());
	for (size_t i = 0; i < now.size(); i++) map_merged_pose_[i] = now[i].pose;
	map_merges_++;
	odometry_->runOnMap(
	    [this, move = std::move(move), segments, voxels](map::CForestMap& m)
	    {
		    const auto t0 = std::chrono::steady_clock::now();
		    const double rss0 = core::currentRssMb();
		    move(m);
		    // Read by the mapping thread after a flush only.
		    map_voxels_at_merge_ = m.edgePointCount() + m.planarPointCount();
		    FS_LOG_INFO("CForestMap: "
		                << segments << " segments, " << voxels
		                << " voxels merged into " << map_voxels_at_merge_
		                << " during the run in "
		                << std::chrono::duration<double>(
		                       std::chrono::steady_clock::now() - t0)
		                       .count()
		                << " s; RSS " << rss0 << " -> " << core::currentRssMb()
		                << " MB");
	    });
}

void MappingPipeline::correctForestMap(const core::Trajectory& as_mapped,
                                       const core::Trajectory& target)
{
	forestMapCorrection(as_mapped, target)(map_);
}

std::function<void(map::CForestMap&)> MappingPipeline::forestMapCorrection(
    const core::Trajectory& as_mapped, const core::Trajectory& target)
{
	// A voxel averages many scans: it moves with the correction of the
	// scan of its segment that passed nearest to it (horizontally, where
	// its voxels are), like the tree columns. Segments keep the voxels
	// mapped before and after each correction apart, so a revisited place
	// does not mix a drifted first pass with the corrected second one.
	// In long runs the segments are merged during the run too (at the
	// estimate then, mergeForestMapSegments): the first scans' voxels are
	// where that merge put them.
	core::Trajectory mapped = as_mapped;
	for (size_t i = 0; i < map_merged_pose_.size() && i < mapped.size(); i++)
		mapped[i].pose = map_merged_pose_[i];
	struct Plan
	{
		std::vector<Eigen::Isometry3f,
		            Eigen::aligned_allocator<Eigen::Isometry3f>>
		    C;
		std::vector<Eigen::Vector2d> xy;  ///< scans as mapped
		/** Per segment: its scans 0.5 m apart. */
		std::vector<std::vector<size_t>> cand;
	};
	auto plan = std::make_shared<Plan>();
	plan->C = scanCorrections(target, mapped);
	plan->xy = scanPositions(mapped);
	if (map_.segmentCount() != map_segment_first_scan_.size() + 1)
		throw std::logic_error("back-end: CForestMap segment bookkeeping");
	// Candidates per segment: its scans 0.5 m apart, without the scan
	// mapped before the correction that ended it (its pose was corrected).
	auto& cand = plan->cand;
	cand.resize(map_.segmentCount());
	for (size_t s = 0; s < cand.size(); s++)
	{
		const size_t a = s == 0 ? 0 : map_segment_first_scan_[s - 1];
		const size_t b = s + 1 < cand.size() ? map_segment_first_scan_[s] - 1
		                                     : mapped.size();
		for (size_t i = a; i < std::min(b, mapped.size()); i++)
			if (cand[s].empty() ||
			    (plan->xy[i] - plan->xy[cand[s].back()]).norm() >= 0.5)
				cand[s].push_back(i);
		if (cand[s].empty()) cand[s].push_back(std::min(a, mapped.size() - 1));
	}
	map_segment_first_scan_.clear();
	return [plan](map::CForestMap& m)
	{
		// Nearest candidate per 1 m cell, computed once.
		constexpr double kCell = 1.0;
		std::unordered_map<uint64_t, size_t> nearest;
		m.transformSegments(
		    [&](size_t s, const Eigen::Vector3f& c) -> Eigen::Isometry3f
		    {
			    const int64_t i =
			        static_cast<int64_t>(std::floor(c.x() / kCell));
			    const int64_t j =
			        static_cast<int64_t>(std::floor(c.y() / kCell));
			    const uint64_t key = (uint64_t(s) << 48) |
			                         ((uint64_t(i) & 0xffffff) << 24) |
			                         (uint64_t(j) & 0xffffff);
			    auto it = nearest.find(key);
			    if (it == nearest.end())
			    {
				    const Eigen::Vector2d q((i + 0.5) * kCell,
				                            (j + 0.5) * kCell);
				    size_t best = plan->cand[s].front();
				    double bd = 1e300;
				    for (const size_t n : plan->cand[s])
				    {
					    const double d = (plan->xy[n] - q).squaredNorm();
					    if (d < bd) bd = d, best = n;
				    }
				    it = nearest.emplace(key, best).first;
			    }
			    return plan->C[it->second];
		    });
	};
}

size_t MappingPipeline::correctionBytes() const
{
	size_t n = core::vectorBytes(anchors_) + core::vectorBytes(kf_pose_) +
	           core::vectorBytes(map_merged_pose_) +
	           core::vectorBytes(map_segment_first_scan_) +
	           core::vectorBytes(tree_merge_estimates_);
	for (const auto& e : tree_merge_estimates_) n += core::vectorBytes(e.X);
	return n;
}

std::optional<outputs::GeoOptions> MappingPipeline::estimatedGeoreference()
    const
{
	if (!backend_ || !gnss_origin_) return std::nullopt;
	const auto e = backend_->mapToEnu();
	if (!e) return std::nullopt;
	outputs::GeoOptions g;
	g.mode = "enu_origin";
	g.origin_lat_deg = gnss_origin_->enu.LatitudeOrigin();
	g.origin_lon_deg = gnss_origin_->enu.LongitudeOrigin();
	g.origin_alt_m = gnss_origin_->enu.HeightOrigin();
	g.map_to_enu_yaw_rad = e->yaw;
	g.map_to_enu_x_m = e->t.x();
	g.map_to_enu_y_m = e->t.y();
	g.map_to_enu_z_m = e->t.z();
	return g;
}

}  // namespace forest_slam::pipeline
