#include <forest_slam/core/config.h>
#include <forest_slam/core/log.h>
#include <forest_slam/odometry/lidar_odometry.h>

#include <algorithm>
#include <chrono>
#include <unordered_map>

namespace forest_slam::odometry
{
void OdometryOptions::loadFromConfigFile(
	const mrpt::config::CConfigFileBase& c, const std::string& s)
{
	FS_LOAD(c, s, local_map_radius_m);
	FS_LOAD(c, s, target_rebuild_distance_m);
	FS_LOAD(c, s, target_rebuild_scans);
	FS_LOAD(c, s, min_matches);
	FS_LOAD(c, s, degeneracy_ratio);
	const std::string where = core::configOrigin(c) + ": [" + s + "] ";
	if (!(local_map_radius_m > 0))
		throw core::ConfigError(where + "local_map_radius_m must be > 0");
	if (!(target_rebuild_distance_m >= 0) || target_rebuild_scans < 1)
		throw core::ConfigError(
			where + "target_rebuild_distance_m must be >= 0, target_rebuild_scans >= 1");
	if (min_matches < 6) throw core::ConfigError(where + "min_matches must be >= 6");
}

void OdometryOptions::saveToConfigFile(
	mrpt::config::CConfigFileBase& c, const std::string& s) const
{
	c.write(s, "local_map_radius_m", local_map_radius_m);
	c.write(s, "target_rebuild_distance_m", target_rebuild_distance_m);
	c.write(s, "target_rebuild_scans", target_rebuild_scans);
	c.write(s, "min_matches", min_matches);
	c.write(s, "degeneracy_ratio", degeneracy_ratio);
}

LidarOdometry::LidarOdometry(const OdometryConfig& cfg, map::CForestMap& map)
	: cfg_(cfg), map_(map), lattice_(cfg.ground)
{
}

namespace
{
using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point& t)
{
	const auto now = Clock::now();
	const double ms = std::chrono::duration<double, std::milli>(now - t).count();
	t = now;
	return ms;
}
}  // namespace

LidarOdometry::Prepared LidarOdometry::prepare(
	const core::ScanPoints& scan, const Eigen::Isometry3d& motion,
	const Eigen::Isometry3d& predicted, ScanTiming& timing)
{
	auto t = Clock::now();
	Prepared out;
	// Deskew into the frame of the first firing: a point fired at t moves
	// with the motion fraction t/sweep (one transform per firing column).
	const double sweep = std::max(1e-6, scan.sweep_s);
	std::unordered_map<uint32_t, Eigen::Isometry3f> column_T;
	auto& fin = out.points;
	fin.reserve(scan.points.size());
	for (const auto& p : scan.points)
	{
		const Eigen::Vector3f raw(p.x, p.y, p.z);
		if (!raw.allFinite()) continue;
		auto it = column_T.find(p.column);
		if (it == column_T.end())
			it = column_T
					 .emplace(p.column, core::interpolateIsometry(
											Eigen::Isometry3d::Identity(), motion,
											std::clamp(p.t_s / sweep, 0.0, 1.0))
											.cast<float>())
					 .first;
		features::FeatureInputPoint f;
		f.xyz = it->second * raw;
		f.ring = p.ring;
		f.column = p.column;
		fin.push_back(f);
	}
	timing.deskew_ms += msSince(t);

	// Ground labels in the gravity-aligned map frame (predicted pose).
	const Eigen::Isometry3f Tp = predicted.cast<float>();
	std::vector<Eigen::Vector3f> in_map(fin.size());
	for (size_t i = 0; i < fin.size(); i++) in_map[i] = Tp * fin[i].xyz;
	const auto ground = lattice_.labelScan(in_map, predicted.translation());
	timing.ground_ms += msSince(t);

	// Clusters of the non-ground points (sensor frame).
	std::vector<Eigen::Vector3f> ng;
	std::vector<uint32_t> ng_idx;
	for (size_t i = 0; i < fin.size(); i++)
	{
		fin[i].ground = ground[i] != 0;
		if (!fin[i].ground)
		{
			ng.push_back(fin[i].xyz);
			ng_idx.push_back(static_cast<uint32_t>(i));
		}
	}
	const auto cl = cluster::hierarchicalKMeans(ng, cfg_.cluster);
	for (size_t k = 0; k < ng_idx.size(); k++) fin[ng_idx[k]].cluster = cl.cluster[k];
	timing.cluster_ms += msSince(t);

	// Features for registration; the decision factor of every point for the
	// map insertion.
	out.feats = features::extractFeatures(fin, cfg_.features);
	for (auto i : out.feats.edges) out.edges.push_back(fin[i].xyz);
	for (auto i : out.feats.planar) out.planar.push_back(fin[i].xyz);
	timing.features_ms += msSince(t);
	return out;
}

void LidarOdometry::insert(const Prepared& s, const Eigen::Isometry3d& pose)
{
	// The whole deskewed scan, not only the selected features, split by its
	// decision factor into the edge and planar clouds (§4.5); the voxel
	// filters keep the map small.
	std::vector<Eigen::Vector3f> map_edges, map_planar;
	for (size_t i = 0; i < s.points.size(); i++)
		(s.feats.smoothness[i] > cfg_.features.edge_threshold ? map_edges : map_planar)
			.push_back(s.points[i].xyz);
	map_.insertFeatures(map_edges, map_planar, pose);
}

RegistrationResult LidarOdometry::registerToMap(
	const Prepared& s, const Eigen::Isometry3d& predicted)
{
	const auto& o = cfg_.odometry;
	if (scans_since_target_ < 0 || scans_since_target_ >= o.target_rebuild_scans ||
		(predicted.translation() - target_centre_).norm() > o.target_rebuild_distance_m)
	{
		std::vector<Eigen::Vector3f> me, mp;
		map_.collectNear(predicted.translation(), o.local_map_radius_m, me, mp);
		target_.build(me, mp);
		target_centre_ = predicted.translation();
		scans_since_target_ = 0;
	}
	scans_since_target_++;
	return registerFeatures(target_, s.edges, s.planar, predicted, cfg_.registration, &predicted);
}

OdometryStep LidarOdometry::processScan(const core::ScanPoints& scan)
{
	OdometryStep step;
	const double stamp = scan.stamp_s;
	// 1. Prediction: constant velocity, scaled to the time since last scan.
	Eigen::Isometry3d predicted = initial_pose_;
	Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();  // over this sweep
	if (scans_ > 0)
	{
		const double dt = stamp - last_stamp_s_;
		const double period = scan.sweep_s > 0 ? scan.sweep_s : last_period_s_;
		motion = core::interpolateIsometry(Eigen::Isometry3d::Identity(), velocity_,
										   period / last_period_s_);
		predicted = last_pose_ * core::interpolateIsometry(Eigen::Isometry3d::Identity(),
														   velocity_, dt / last_period_s_);
	}

	// 2-5. Deskew, ground, clusters, features.
	const Prepared cur = prepare(scan, motion, predicted, step.timing);
	step.edges = cur.edges.size();
	step.planar = cur.planar.size();

	// 6. Scan-to-map registration.
	auto t = Clock::now();
	Eigen::Isometry3d pose = predicted;
	if (scans_ > 0 && !map_.isEmpty())
	{
		step.registration = registerToMap(cur, predicted);
		if (scans_ == 1 && first_scan_)
		{
			// Bootstrap: the first scan went into the map without deskew
			// (motion unknown). Now that the motion is estimated, rebuild the
			// map from the deskewed first scan and register again.
			// A few rounds: each better motion gives a better first scan.
			const double dt = std::max(1e-3, stamp - last_stamp_s_);
			for (int round = 0; round < 3; round++)
			{
				const Eigen::Isometry3d v = last_pose_.inverse() * step.registration.T;
				const Eigen::Isometry3d motion0 = core::interpolateIsometry(
					Eigen::Isometry3d::Identity(), v, first_scan_->sweep_s / dt);
				ScanTiming ignored;
				map_.clear();
				insert(prepare(*first_scan_, motion0, last_pose_, ignored), last_pose_);
				scans_since_target_ = -1;  // the map changed: rebuild
				step.registration = registerToMap(cur, predicted);
			}
		}
		first_scan_.reset();
		const auto& r = step.registration;
		const auto& ev = r.information_eigenvalues;
		step.degenerate = ev[5] > 0 && ev[0] < cfg_.odometry.degeneracy_ratio * ev[5];
		if (r.edge_matches + r.planar_matches >= static_cast<size_t>(cfg_.odometry.min_matches))
		{
			pose = r.T;
			step.registered = true;
		}
		else
			core::logOnce(core::LogLevel::Warn, "odometry-few-matches",
						  "scan at t=" + std::to_string(stamp) + " s: only " +
							  std::to_string(r.edge_matches + r.planar_matches) +
							  " feature matches; the motion model carries the pose "
							  "(further such scans counted in the summary)");
		if (step.degenerate)
			core::logOnce(core::LogLevel::Warn, "odometry-degenerate",
						  "scan at t=" + std::to_string(stamp) +
							  " s: degenerate geometry (few constraints in some "
							  "direction, the motion model holds it); further "
							  "occurrences counted");
	}
	else if (scans_ == 0)
		first_scan_ = scan;
	step.timing.register_ms = msSince(t);

	// 7. Map update and motion model.
	insert(cur, pose);
	if (scans_ > 0)
	{
		last_period_s_ = std::max(1e-3, stamp - last_stamp_s_);
		velocity_ = last_pose_.inverse() * pose;
	}
	last_pose_ = pose;
	last_stamp_s_ = stamp;
	scans_++;
	step.pose = {stamp, pose};
	step.timing.insert_ms = msSince(t);
	return step;
}

}  // namespace forest_slam::odometry
