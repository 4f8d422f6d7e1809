#include <forest_slam/core/config.h>
#include <forest_slam/core/log.h>
#include <forest_slam/features/range_smoothing.h>
#include <forest_slam/odometry/degeneracy.h>
#include <forest_slam/odometry/lidar_odometry.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>

namespace forest_slam::odometry
{
void OdometryOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                         const std::string& s)
{
	FS_LOAD(c, s, prune_every_scans);
	FS_LOAD(c, s, map_insert_every_scans);
	FS_LOAD(c, s, map_insert_far_m);
	FS_LOAD(c, s, use_imu);
	FS_LOAD(c, s, min_matches);
	FS_LOAD(c, s, degeneracy_ratio);
	FS_LOAD(c, s, degenerate_hold_ratio);
	FS_LOAD(c, s, async_map_insert);
	FS_LOAD(c, s, imu_translation);
	FS_LOAD(c, s, degenerate_velocity_window_s);
	FS_LOAD(c, s, sweep_motion_without_imu);
	FS_LOAD(c, s, start_rotation_sigma_deg);
	FS_LOAD(c, s, start_radius_m);
	FS_LOAD(c, s, start_plane_spread_ratio);
	const std::string where = core::configOrigin(c) + ": [" + s + "] ";
	if (prune_every_scans < 1)
		throw core::ConfigError(where + "prune_every_scans must be >= 1");
	if (map_insert_every_scans < 1)
		throw core::ConfigError(where +
		                        "map_insert_every_scans: expected a whole "
		                        "number >= 1");
	if (!(map_insert_far_m >= 0))
		throw core::ConfigError(where + "map_insert_far_m: expected >= 0");
	if (min_matches < 6)
		throw core::ConfigError(where + "min_matches must be >= 6");
	if (!(degenerate_hold_ratio >= 0 && degenerate_hold_ratio < 1))
		throw core::ConfigError(where +
		                        "degenerate_hold_ratio: expected 0 <= x < 1");
	if (!(degenerate_velocity_window_s >= 0))
		throw core::ConfigError(where +
		                        "degenerate_velocity_window_s: expected >= 0");
	if (!(start_rotation_sigma_deg >= 0))
		throw core::ConfigError(where +
		                        "start_rotation_sigma_deg: expected >= 0");
	if (!(start_radius_m >= 0))
		throw core::ConfigError(where + "start_radius_m: expected >= 0");
	if (!(start_plane_spread_ratio >= 0 && start_plane_spread_ratio <= 1))
		throw core::ConfigError(
		    where + "start_plane_spread_ratio: expected 0 <= x <= 1");
}

void OdometryOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                       const std::string& s) const
{
	c.write(s, "prune_every_scans", prune_every_scans);
	c.write(s, "map_insert_every_scans", map_insert_every_scans);
	c.write(s, "map_insert_far_m", map_insert_far_m);
	c.write(s, "use_imu", use_imu);
	c.write(s, "min_matches", min_matches);
	c.write(s, "degeneracy_ratio", degeneracy_ratio);
	c.write(s, "degenerate_hold_ratio", degenerate_hold_ratio);
	c.write(s, "async_map_insert", async_map_insert);
	c.write(s, "imu_translation", imu_translation);
	c.write(s, "degenerate_velocity_window_s", degenerate_velocity_window_s);
	c.write(s, "sweep_motion_without_imu", sweep_motion_without_imu);
	c.write(s, "start_rotation_sigma_deg", start_rotation_sigma_deg);
	c.write(s, "start_radius_m", start_radius_m);
	c.write(s, "start_plane_spread_ratio", start_plane_spread_ratio);
}

namespace
{
/** Jobs queued on the CForestMap thread at most: a scan's insertion is a
 * few milliseconds, a tree-layer column detection (runOnMap) hundreds, and
 * the queue absorbs one without stopping the odometry (a job holds one
 * scan's points, ~0.3 MB; a scan queues two jobs, its insertion and the
 * tree layer's). The thread runs at a low priority (nice 19 for a recorded
 * rawlog), in the gaps the odometry leaves: with 48 jobs the odometry waited
 * for room 11 s of the robot run's 170 s, often with one core idle; with
 * 256, 1.5 s (and the back-end's flushes waited 3.6 s instead of 0.1). 128 ran
 * as fast in pairs, with half the memory held back at worst
 * (doc/performance.md, forty-seventh session). */
constexpr size_t kMapQueue = 128;
}  // namespace

LidarOdometry::LidarOdometry(const OdometryConfig& cfg, map::CForestMap& map)
    : cfg_(cfg),
      local_map_(cfg.local_map, cfg.registration.plane_flatness),
      map_(map),
      inserter_(map, cfg.odometry.async_map_insert ? kMapQueue : 0),
      local_worker_(cfg.odometry.async_map_insert ? 2 : 0, "fs-localmap"),
      lattice_(cfg.ground)
{
}

namespace
{
using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point& t)
{
	const auto now = Clock::now();
	const double ms =
	    std::chrono::duration<double, std::milli>(now - t).count();
	t = now;
	return ms;
}
}  // namespace

Eigen::Matrix3d LidarOdometry::imuRotation(double t0_s, double t1_s) const
{
	const Eigen::Matrix3d Rb =
	    imu_->rotationBetween(t0_s, t1_s).toRotationMatrix();
	return R_body_lidar_.transpose() * Rb * R_body_lidar_;
}

Eigen::Vector3d LidarOdometry::gravityInMap() const
{
	return {0, 0, -imu_->filter().options().gravity};
}

imu::AccelIntegral LidarOdometry::accelSinceLastScan(
    double stamp_s, Eigen::Matrix3d& R_map_body) const
{
	R_map_body = last_pose_.linear() * R_body_lidar_.transpose();
	return imu_->integrateAcceleration(last_stamp_s_, stamp_s,
	                                   R_map_body.transpose() * gravityInMap());
}

Eigen::Isometry3d SweepMotion::at(double s) const
{
	const double a = std::clamp(s / std::max(1e-6, sweep_s), 0.0, 1.0);
	Eigen::Isometry3d T =
	    core::interpolateIsometry(Eigen::Isometry3d::Identity(), end, a);
	if (imu)
		T.linear() = R_body_lidar.transpose() *
		             imu->rotationBetween(t0_s, t0_s + s).toRotationMatrix() *
		             R_body_lidar;
	if (imu && accel)
		T.translation() =
		    R_body_lidar.transpose() *
		    (v0_body * s +
		     imu->integrateAcceleration(t0_s, t0_s + s, gravity_body).dp);
	return T;
}

size_t labelGroundAndCluster(std::vector<features::FeatureInputPoint>& pts,
                             const std::vector<uint8_t>& ground,
                             const cluster::ClusterOptions& o)
{
	std::vector<Eigen::Vector3f> ng;
	std::vector<uint32_t> ng_idx;
	for (size_t i = 0; i < pts.size(); i++)
	{
		pts[i].ground = ground[i] != 0;
		if (!pts[i].ground)
		{
			ng.push_back(pts[i].xyz);
			ng_idx.push_back(static_cast<uint32_t>(i));
		}
	}
	const auto cl = cluster::hierarchicalKMeans(ng, o);
	for (size_t k = 0; k < ng_idx.size(); k++)
		pts[ng_idx[k]].cluster = cl.cluster[k];
	return cl.clusterCount();
}

namespace
{
/** SweepMotion at evenly spaced instants of the sweep, interpolated (slerp,
 * lerp) in between: at() integrates the IMU from the start of the sweep, so
 * calling it for each of a VLP-16's ~1800 firing columns was quadratic in
 * the IMU samples per sweep. Between knots 1.6 ms apart the rotation rate
 * and the acceleration barely change: the interpolation is within microns
 * and millidegrees of at(). */
class SweepTable
{
   public:
	explicit SweepTable(const SweepMotion& m) : m_(m)
	{
		step_s_ = std::max(1e-6, m.sweep_s) / kKnots;
		for (int k = 0; k <= kKnots; k++)
		{
			const Eigen::Isometry3d T = m.at(k * step_s_);
			q_[k] = Eigen::Quaterniond(T.linear());
			t_[k] = T.translation();
		}
	}
	Eigen::Isometry3d at(double s) const
	{
		const double u = s / step_s_;
		if (!(u >= 0 && u <= kKnots)) return m_.at(s);  // outside the sweep
		const int k = std::min(kKnots - 1, static_cast<int>(u));
		const double a = u - k;
		Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
		T.linear() = q_[k].slerp(a, q_[k + 1]).toRotationMatrix();
		T.translation() = (1 - a) * t_[k] + a * t_[k + 1];
		return T;
	}

   private:
	static constexpr int kKnots = 64;
	const SweepMotion& m_;
	double step_s_;
	Eigen::Quaterniond q_[kKnots + 1];
	Eigen::Vector3d t_[kKnots + 1];
};
}  // namespace

std::vector<features::FeatureInputPoint> deskewScan(
    const core::ScanPoints& scan, const SweepMotion& motion,
    std::vector<float>* times_s)
{
	if (times_s) times_s->clear();
	// A point fired at time s moves with the sensor's motion from 0 to s.
	// Points come column by column (core::unpackRotatingScan): one
	// transform per column.
	const SweepTable table(motion);
	std::vector<features::FeatureInputPoint> fin;
	fin.reserve(scan.points.size());
	Eigen::Isometry3f T_col = Eigen::Isometry3f::Identity();
	int64_t col = -1;
	for (const auto& p : scan.points)
	{
		const Eigen::Vector3f raw(p.x, p.y, p.z);
		if (!raw.allFinite()) continue;
		if (p.column != col)
			T_col = table.at(p.t_s).cast<float>(), col = p.column;
		features::FeatureInputPoint f;
		f.xyz = T_col * raw;
		f.ring = p.ring;
		f.column = p.column;
		fin.push_back(f);
		if (times_s) times_s->push_back(p.t_s);
	}
	return fin;
}

LidarOdometry::Prepared LidarOdometry::prepare(
    const core::ScanPoints& scan, const SweepMotion& motion,
    const Eigen::Isometry3d& predicted, ScanTiming& timing)
{
	auto t = Clock::now();
	Prepared out;
	// Deskew into the frame of the first firing (IMU rotation when
	// available, constant-velocity translation).
	std::vector<float> times;
	out.points = deskewScan(scan, motion, &times);
	auto& fin = out.points;
	timing.deskew_ms += msSince(t);

	// Ground labels in the gravity-aligned map frame (predicted pose).
	const Eigen::Isometry3f Tp = predicted.cast<float>();
	std::vector<Eigen::Vector3f> in_map(fin.size());
	for (size_t i = 0; i < fin.size(); i++) in_map[i] = Tp * fin[i].xyz;
	const auto ground = lattice_.labelScan(in_map, predicted.translation());
	timing.ground_ms += msSince(t);

	// Clusters of the non-ground points (sensor frame).
	labelGroundAndCluster(fin, ground, cfg_.cluster);
	timing.cluster_ms += msSince(t);

	// Features for registration; the decision factor of every point for the
	// map insertion.
	const features::RingLines rings = features::ringLines(fin);
	out.feats = features::extractFeatures(fin, rings, cfg_.features);
	out.matched =
	    features::smoothRanges(fin, rings, cfg_.features.range_smoothing);
	const float inv_sweep =
	    1.0f / static_cast<float>(std::max(1e-6, motion.sweep_s));
	for (auto i : out.feats.edges)
	{
		out.edges.push_back(out.matched[i]);
		out.edge_fraction.push_back(std::clamp(times[i] * inv_sweep, 0.f, 1.f));
	}
	for (auto i : out.feats.planar)
	{
		out.planar.push_back(out.matched[i]);
		out.planar_fraction.push_back(
		    std::clamp(times[i] * inv_sweep, 0.f, 1.f));
	}
	timing.features_ms += msSince(t);
	return out;
}

void LidarOdometry::insert(const Prepared& s, const Eigen::Isometry3d& pose,
                           float min_range_m)
{
	const float min_r2 = min_range_m * min_range_m;
	// The whole deskewed scan, not only the selected features, split by its
	// decision factor into the edge and planar clouds (§4.5); the voxel
	// filters keep the map small.
	std::vector<Eigen::Vector3f> map_edges, map_planar, local_edges,
	    local_planar;
	for (size_t i = 0; i < s.points.size(); i++)
	{
		if (min_r2 > 0 && s.points[i].xyz.squaredNorm() < min_r2) continue;
		const bool edge = s.feats.smoothness[i] > cfg_.features.edge_threshold;
		(edge ? map_edges : map_planar).push_back(s.points[i].xyz);
		(edge ? local_edges : local_planar).push_back(s.matched[i]);
	}
	// The odometry's local map in the map frame (the positions it matches
	// with), and the CForestMap with the measured sensor-frame points, each
	// on its worker thread.
	local_worker_.push(
	    [this, T = Eigen::Isometry3f(pose.cast<float>()),
	     e = std::move(local_edges), p = std::move(local_planar)]() mutable
	    {
		    for (auto& x : e) x = T * x;
		    for (auto& x : p) x = T * x;
		    local_map_.insert(e, p);
	    });
	inserter_.push(std::move(map_edges), std::move(map_planar), pose);
}

OdometryStep LidarOdometry::processScan(const core::ScanPoints& scan)
{
	OdometryStep step;
	const double stamp = scan.stamp_s;
	const double sweep = scan.sweep_s > 0 ? scan.sweep_s : last_period_s_;
	// 1. Prediction: constant velocity scaled to the time since the last
	// scan; the IMU, when it covers the interval, gives the rotation.
	const bool use_imu =
	    imu_ && cfg_.odometry.use_imu &&
	    imu_->covers(scans_ > 0 ? last_stamp_s_ : stamp, stamp + sweep);
	step.imu_used = use_imu;
	Eigen::Isometry3d predicted = initial_pose_;
	SweepMotion motion;
	motion.imu = use_imu ? imu_ : nullptr;
	motion.R_body_lidar = R_body_lidar_;
	motion.t0_s = stamp;
	motion.sweep_s = sweep;
	if (scans_ > 0)
	{
		const double dt = stamp - last_stamp_s_;
		motion.end = core::interpolateIsometry(
		    Eigen::Isometry3d::Identity(), velocity_, sweep / last_period_s_);
		Eigen::Isometry3d delta = core::interpolateIsometry(
		    Eigen::Isometry3d::Identity(), velocity_, dt / last_period_s_);
		if (use_imu) delta.linear() = imuRotation(last_stamp_s_, stamp);
		// After a lidar gap (dropped scans): the body-frame velocity held
		// step by step while the IMU turns the frame, an arc instead of a
		// straight chord (degeneracy.h).
		if (use_imu && dt > 1.5 * last_period_s_)
			delta = predictAcrossGap(
			    velocity_, last_period_s_, last_stamp_s_, stamp,
			    [this](double a, double b) { return imuRotation(a, b); });
		predicted = last_pose_ * delta;
		// Accelerometer translation: the velocity at the last scan plus the
		// integrated acceleration, for the prediction and for this sweep.
		// Not across a lidar gap: over seconds the accelerometer's bias
		// (and the tilt of "down") integrate into decimetres, the body
		// velocity held through the IMU's turn does better.
		if (use_imu && cfg_.odometry.imu_translation && velocity_map_known_ &&
		    !(dt > 1.5 * last_period_s_))
		{
			Eigen::Matrix3d R_mb;
			const imu::AccelIntegral a = accelSinceLastScan(stamp, R_mb);
			predicted.translation() =
			    last_pose_.translation() + velocity_map_ * dt + R_mb * a.dp;
			const Eigen::Matrix3d R_mb_now =
			    predicted.linear() * R_body_lidar_.transpose();
			motion.accel = true;
			motion.v0_body =
			    R_mb_now.transpose() * (velocity_map_ + R_mb * a.dv);
			motion.gravity_body = R_mb_now.transpose() * gravityInMap();
		}
	}
	RegistrationPriors priors;
	priors.motion = &predicted;
	const std::optional<Eigen::Vector3d> up =
	    use_imu ? imu_->upAt(stamp, R_body_lidar_) : std::nullopt;
	if (up)
		priors.up_in_source = &*up;
	else if (imu_ && cfg_.odometry.use_imu && scans_ > 0)
		core::logOnce(
		    core::LogLevel::Warn, "odometry-imu-gap",
		    "scan at t=" + std::to_string(stamp) +
		        " s: no IMU samples cover it; constant-velocity prediction and "
		        "deskew, no gravity prior (further such scans not logged)");

	// 2-5. Deskew, ground, clusters, features.
	Prepared cur = prepare(scan, motion, predicted, step.timing);
	// No gyro over this sweep while the rig has one (an IMU gap): the
	// registration estimates the sweep's motion too.
	const bool sweep_free = imu_ && cfg_.odometry.use_imu && !use_imu &&
	                        cfg_.odometry.sweep_motion_without_imu &&
	                        scans_ > 1;
	if (sweep_free)
	{
		priors.edge_fraction = &cur.edge_fraction;
		priors.planar_fraction = &cur.planar_fraction;
	}
	step.edges = cur.edges.size();
	step.planar = cur.planar.size();

	// 6. Scan-to-map registration.
	auto t = Clock::now();
	Eigen::Isometry3d pose = predicted;
	local_worker_.flush();  // the last scan is in the local map
	if (scans_ > 0 && !local_map_.empty())
	{
		// Without the gyro the predicted rotation is as uncertain as the
		// sweep's motion (a handheld gait: 3-4 deg RMS from one scan to the
		// next, whatever the model): a 1 deg prior held the registration
		// degrees off, and the scans inserted so tilted the local map
		// (IMU gap of the tiny scenario: ATE 0.064 m; 0.012 m with 5 deg).
		RegistrationOptions ropt = cfg_.registration;
		if (sweep_free)
			ropt.prior_rotation_sigma_deg =
			    std::max(ropt.prior_rotation_sigma_deg,
			             kSweepTwistSigmaRad * 180 / M_PI);
		// The start: the gyro holds the rotation until the lidar has left
		// the first viewpoint (OdometryOptions::start_rotation_sigma_deg).
		left_start_ =
		    left_start_ ||
		    (predicted.translation() - initial_pose_.translation()).norm() >=
		        cfg_.odometry.start_radius_m;
		if (use_imu && !left_start_ &&
		    cfg_.odometry.start_rotation_sigma_deg > 0)
			ropt.prior_rotation_sigma_deg =
			    cfg_.odometry.start_rotation_sigma_deg;
		if (!left_start_)
			ropt.min_plane_spread_ratio =
			    cfg_.odometry.start_plane_spread_ratio;
		step.registration = registerFeatures(local_map_, cur.edges, cur.planar,
		                                     predicted, ropt, priors);
		if (scans_ == 1 && first_scan_)
		{
			// Bootstrap: the first scan went into the map without the
			// translation part of the deskew (motion unknown). Now that the
			// motion is estimated, rebuild the map from the deskewed first scan
			// and register again; a few rounds: each better motion gives a
			// better map.
			const double dt = std::max(1e-3, stamp - last_stamp_s_);
			for (int round = 0; round < 3; round++)
			{
				const Eigen::Isometry3d v =
				    last_pose_.inverse() * step.registration.T;
				SweepMotion m0;
				m0.imu = first_scan_imu_ ? imu_ : nullptr;
				m0.R_body_lidar = R_body_lidar_;
				m0.t0_s = first_scan_->stamp_s;
				m0.sweep_s = first_scan_->sweep_s > 0 ? first_scan_->sweep_s
				                                      : last_period_s_;
				m0.end =
				    core::interpolateIsometry(Eigen::Isometry3d::Identity(), v,
				                              first_scan_->sweep_s / dt);
				ScanTiming ignored;
				inserter_.flush();
				map_.clear();
				local_map_.clear();
				insert(prepare(*first_scan_, m0, last_pose_, ignored),
				       last_pose_);
				local_worker_.flush();
				step.registration = registerFeatures(
				    local_map_, cur.edges, cur.planar, predicted, ropt, priors);
			}
		}
		first_scan_.reset();
		if (sweep_free)
		{
			// The twist is linearised: registered again from the scan
			// deskewed with it, three passes in all (one pass: ATE 0.040 m
			// on the tiny IMU gap, three: 0.012 m).
			constexpr int kPasses = 3;
			for (int pass = 0;; pass++)
			{
				// The sweep's motion with the registration's correction
				// (exp(s w) q + s v; to first order the same motion over
				// the sweep), the scan deskewed again with it.
				const auto& tw = step.registration.sweep_twist;
				Eigen::Isometry3d C = Eigen::Isometry3d::Identity();
				C.linear() =
				    Eigen::AngleAxisd(
				        tw.head<3>().norm(),
				        tw.head<3>().norm() > 0
				            ? Eigen::Vector3d(tw.head<3>().normalized())
				            : Eigen::Vector3d::UnitZ())
				        .toRotationMatrix();
				C.translation() = tw.tail<3>();
				motion.end = C * motion.end;
				const auto redone = deskewScan(scan, motion);
				for (size_t i = 0; i < redone.size() && i < cur.points.size();
				     i++)
					cur.points[i].xyz = redone[i].xyz;
				for (size_t i = 0; i < cur.feats.edges.size(); i++)
					cur.edges[i] = cur.points[cur.feats.edges[i]].xyz;
				for (size_t i = 0; i < cur.feats.planar.size(); i++)
					cur.planar[i] = cur.points[cur.feats.planar[i]].xyz;
				if (pass + 1 >= kPasses) break;
				step.registration =
				    registerFeatures(local_map_, cur.edges, cur.planar,
				                     step.registration.T, ropt, priors);
			}
		}
		const auto& r = step.registration;
		const Eigen::Matrix<double, 6, 1> ev =
		    Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>>(
		        scaledInformation(r.information, r.lever_arm_m))
		        .eigenvalues();
		step.degenerate =
		    ev[5] > 0 && ev[0] < cfg_.odometry.degeneracy_ratio * ev[5];
		if (r.edge_matches + r.planar_matches >=
		    static_cast<size_t>(cfg_.odometry.min_matches))
		{
			pose = r.T;
			step.registered = true;

			// Degenerate place: the prediction holds the weak directions,
			// if its velocity came from well-constrained scans (a wrong
			// one would be carried on unchecked).
			if (step.degenerate && velocity_trusted_ &&
			    cfg_.odometry.degenerate_hold_ratio > 0)
			{
				// The held directions follow the mean velocity before the
				// stretch rather than the last scan's.
				Eigen::Isometry3d hold = predicted;
				if (cfg_.odometry.degenerate_velocity_window_s > 0)
					if (const auto d = meanVelocityStep(
					        track_, cfg_.odometry.degenerate_velocity_window_s,
					        last_stamp_s_, stamp,
					        headingOf(predicted.linear())))
						hold.translation() = last_pose_.translation() + *d;
				pose = remapDegenerate(hold, r.T, r.information, r.lever_arm_m,
				                       cfg_.odometry.degenerate_hold_ratio);
			}
			else
				velocity_trusted_ = !step.degenerate && scans_ >= 2;
		}
		else
		{
			velocity_trusted_ = false;
			core::logOnce(
			    core::LogLevel::Warn, "odometry-few-matches",
			    "scan at t=" + std::to_string(stamp) + " s: only " +
			        std::to_string(r.edge_matches + r.planar_matches) +
			        " feature matches; the motion model carries the pose "
			        "(further such scans counted in the summary)");
		}
		if (step.degenerate)
			core::logOnce(
			    core::LogLevel::Warn, "odometry-degenerate",
			    "scan at t=" + std::to_string(stamp) +
			        " s: degenerate geometry (few constraints in some "
			        "direction, the motion model holds it); further "
			        "occurrences counted");
	}
	else if (scans_ == 0)
	{
		first_scan_ = scan;
		first_scan_imu_ = use_imu;
	}
	step.timing.register_ms = msSince(t);
	last_deskewed_.clear();
	last_deskewed_.reserve(cur.points.size());
	for (const auto& p : cur.points) last_deskewed_.push_back(p.xyz);

	// 7. Map update and motion model.
	// Whole scans or far points only (OdometryOptions::
	// map_insert_every_scans); whole at the start, where the young map,
	// seen from one viewpoint, sets the yaw the whole map keeps.
	if (!left_start_ || scans_ % cfg_.odometry.map_insert_every_scans == 0)
		insert(cur, pose);
	else if (cfg_.odometry.map_insert_far_m > 0)
		insert(cur, pose, static_cast<float>(cfg_.odometry.map_insert_far_m));
	if (scans_ % cfg_.odometry.prune_every_scans == 0)
		local_worker_.push([this, c = Eigen::Vector3d(pose.translation())]
		                   { local_map_.prune(c); });
	if (scans_ > 0)
	{
		last_period_s_ = std::max(1e-3, stamp - last_stamp_s_);
		velocity_ = last_pose_.inverse() * pose;
		// Velocity at this scan: the mean over the interval plus what the
		// accelerometer says changed since its middle (AccelIntegral).
		// A scan whose weak directions were held on the prediction says
		// nothing new about the velocity there: integrating the
		// accelerometer through a degenerate stretch would let its bias
		// grow into the held directions (3 s open field: ATE 0.052 m
		// against 0.041 m with constant velocity), so constant velocity
		// carries the stretch.
		velocity_map_known_ = use_imu && cfg_.odometry.imu_translation;
		if (velocity_map_known_)
		{
			Eigen::Matrix3d R_mb;
			const imu::AccelIntegral a = accelSinceLastScan(stamp, R_mb);
			velocity_map_ = (pose.translation() - last_pose_.translation()) /
			                    last_period_s_ +
			                R_mb * a.moment;
		}
	}
	track_.push_back({stamp, pose.translation(), headingOf(pose.linear()),
	                  step.registered && !step.degenerate});
	if (track_.size() > kTrackSize) track_.pop_front();
	last_pose_ = pose;
	last_stamp_s_ = stamp;
	scans_++;
	step.pose = {stamp, pose};
	step.timing.insert_ms = msSince(t);
	return step;
}

void LidarOdometry::applyCorrection(const Eigen::Isometry3d& C)
{
	last_pose_ = C * last_pose_;
	initial_pose_ = C * initial_pose_;
	// The accelerometer's velocity is in the map frame: it turns with it
	// (velocity_ is relative to the last pose and needs nothing).
	velocity_map_ = C.linear() * velocity_map_;
	for (auto& q : track_)
	{
		q.p = C * q.p;
		q.heading_rad += headingOf(C.linear());
	}
	local_worker_.flush();
	local_map_.transform(C);
}

}  // namespace forest_slam::odometry
