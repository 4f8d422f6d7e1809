#include <forest_slam/core/atomic_file.h>
#include <forest_slam/core/log.h>
#include <forest_slam/core/progress.h>
#include <forest_slam/io/rawlog_writer.h>
#include <forest_slam/io/tum.h>
#include <forest_slam/sim/bag_writer.h>
#include <forest_slam/sim/faults.h>
#include <forest_slam/sim/gnss_sim.h>
#include <forest_slam/sim/imu_sim.h>
#include <forest_slam/sim/lidar_sim.h>
#include <forest_slam/sim/random.h>
#include <forest_slam/sim/simulator.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>

namespace forest_slam::sim
{
namespace
{
double wallNow()
{
	return std::chrono::duration<double>(
	           std::chrono::steady_clock::now().time_since_epoch())
	    .count();
}

std::string fmt(const char* f, double v)
{
	char buf[64];
	std::snprintf(buf, sizeof(buf), f, v);
	return buf;
}
}  // namespace

Scenario::Scenario(const SimOptions& o) : o_(o.effective())
{
	const Rng master(o_.run.seed);
	Rng rp = master.fork(1);
	path_ = PathPlan::make(o_.motion, rp);
	Rng rs = master.fork(2);
	scene_ = buildScene(o_, path_, rs);
	Rng rm = master.fork(3);
	body_ = planBodyTrajectory(path_, o_.motion, world().terrain(),
	                           o_.run.start_time_unix_s, rm);
	// Map frame: first lidar position, first lidar heading (yaw only).
	const Eigen::Isometry3d T0 =
	    body_.pose(body_.startTime()) * o_.lidar.mount.toIsometry();
	const double yaw = std::atan2(T0.linear()(1, 0), T0.linear()(0, 0));
	Eigen::Isometry3d world_from_map = Eigen::Isometry3d::Identity();
	world_from_map.linear() =
	    Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
	world_from_map.translation() = T0.translation();
	map_from_world_ = world_from_map.inverse();
}

Eigen::Isometry3d Scenario::lidarPoseInMap(double t) const
{
	return map_from_world_ * body_.pose(t) * o_.lidar.mount.toIsometry();
}

core::Trajectory Scenario::lidarTrajectory(double rate_hz) const
{
	core::Trajectory out;
	const double t0 = body_.startTime(), t1 = body_.endTime();
	const long n =
	    static_cast<long>(std::floor((t1 - t0) * rate_hz + 1e-9)) + 1;
	out.reserve(n);
	for (long i = 0; i < n; i++)
	{
		core::StampedPose p;
		p.t_s = t0 + i / rate_hz;
		p.pose = lidarPoseInMap(p.t_s);
		out.push_back(p);
	}
	return out;
}

uint64_t Scenario::lidarSeed() const
{
	return hashCombine(o_.run.seed, 0x11da7);
}
uint64_t Scenario::imuSeed() const
{
	return hashCombine(o_.run.seed, 0x1a4);
}
uint64_t Scenario::gnssSeed() const
{
	return hashCombine(o_.run.seed, 0x6e55);
}

std::string scenarioIni(const Scenario& sc, const RunResult& r)
{
	const auto& o = sc.options();
	std::ostringstream os;
	os << "# forest-sim scenario: the effective parameters of this run (it "
	      "can\n"
	      "# be run again with forest-sim --config scenario.ini) and, in\n"
	      "# [ground_truth], facts about the generated world. Frames:\n"
	      "#   world: local ENU (x east, y north, z up) at the geodetic "
	      "origin\n"
	      "#          [gnss] origin_*, origin on the ground at the start;\n"
	      "#   map:   origin at the first lidar position, x along the first\n"
	      "#          lidar heading (yaw only), z up. All gt_* files are in "
	      "map.\n";
	os << o.toIni() << "\n[ground_truth]\n";
	const Eigen::Isometry3d& M = sc.mapFromWorld();
	const Eigen::Isometry3d W = M.inverse();
	const Eigen::Quaterniond q(M.linear());
	auto kv = [&](const std::string& k, const std::string& v)
	{ os << k << " = " << v << "\n"; };
	kv("map_from_world_xyz_m", fmt("%.6f", M.translation().x()) + " " +
	                               fmt("%.6f", M.translation().y()) + " " +
	                               fmt("%.6f", M.translation().z()));
	kv("map_from_world_quat_xyzw",
	   fmt("%.9f", q.x()) + " " + fmt("%.9f", q.y()) + " " +
	       fmt("%.9f", q.z()) + " " + fmt("%.9f", q.w()));
	kv("map_origin_in_world_xyz_m", fmt("%.6f", W.translation().x()) + " " +
	                                    fmt("%.6f", W.translation().y()) + " " +
	                                    fmt("%.6f", W.translation().z()));
	kv("map_x_axis_yaw_in_world_deg",
	   fmt("%.6f",
	       std::atan2(W.linear()(1, 0), W.linear()(0, 0)) * 180 / M_PI));
	double lat, lon, h;
	enuToGeodetic(W.translation(), o.gnss, lat, lon, h);
	kv("map_origin_lat_deg", fmt("%.9f", lat));
	kv("map_origin_lon_deg", fmt("%.9f", lon));
	kv("map_origin_height_m", fmt("%.4f", h));
	kv("start_time_unix_s", fmt("%.6f", sc.body().startTime()));
	kv("end_time_unix_s", fmt("%.6f", sc.body().endTime()));
	kv("duration_s", fmt("%.3f", r.duration_s));
	kv("path_length_m", fmt("%.2f", r.path_length_m));
	kv("scans", std::to_string(r.scans));
	kv("imu_samples", std::to_string(r.imu));
	kv("gnss_epochs", std::to_string(r.gnss));
	kv("gnss_fixes", std::to_string(r.gnss_fixes));
	kv("points", std::to_string(r.points));
	kv("trees", std::to_string(r.stats.trees));
	kv("saplings", std::to_string(r.stats.saplings));
	kv("shrubs", std::to_string(r.stats.shrubs));
	kv("buildings", std::to_string(r.stats.buildings));
	kv("vehicles", std::to_string(r.stats.vehicles));
	kv("forest_area_ha", fmt("%.4f", r.stats.forest_area_ha));
	kv("stems_per_ha", fmt("%.1f", r.stats.stems_per_ha));
	kv("shrub_cover", fmt("%.4f", r.stats.shrub_cover));
	kv("terrain_elevation_range_m",
	   fmt("%.3f", r.stats.terrain_elevation_range_m));
	kv("terrain_max_slope_deg", fmt("%.3f", r.stats.terrain_max_slope_deg));
	const Eigen::Isometry3d a = sc.lidarPoseInMap(sc.body().startTime());
	const Eigen::Isometry3d b = sc.lidarPoseInMap(sc.body().endTime());
	const Eigen::Isometry3d d = a.inverse() * b;
	kv("return_to_start_translation_m", fmt("%.9f", d.translation().norm()));
	kv("return_to_start_rotation_deg",
	   fmt("%.9f", Eigen::AngleAxisd(d.linear()).angle() * 180 / M_PI));
	return os.str();
}

RunResult runSimulation(const SimOptions& opts, const RunRequest& req)
{
	RunResult res;
	const double wall0 = wallNow();
	core::ensureDirectory(req.out_dir);
	namespace fs = std::filesystem;
	const std::string dir = req.out_dir;
	auto out = [&](const std::string& name)
	{ return (fs::path(dir) / name).string(); };

	FS_LOG_INFO("forest-sim: generating world and motion (seed "
	            << opts.run.seed << ")");
	const Scenario sc(opts);
	const SimOptions& o = sc.options();
	res.stats = sc.scene().stats;
	res.path_length_m = sc.path().length();
	res.duration_s = sc.body().endTime() - sc.body().startTime();
	Rng rng_imu(sc.imuSeed()), rng_gnss(sc.gnssSeed());
	auto imu = simulateImu(sc.body(), o.imu, rng_imu);
	auto gnss = simulateGnss(sc.world(), sc.body(), o.gnss, rng_gnss);
	LidarSimulator lidar(sc.world(), sc.body(), o.lidar, sc.lidarSeed(),
	                     o.run.threads);
	// Injected faults change the recorded streams only (ground truth stays).
	const double t_first = lidar.scanCount() ? lidar.scanTime(0) : 0.0;
	applyImuFaults(o.faults, t_first, imu);
	applyGnssFaults(o.faults, t_first, o.gnss, gnss);
	for (const auto& f : o.faults.describe())
		FS_LOG_INFO("forest-sim: injecting fault: " << f);
	res.setup_wall_s = wallNow() - wall0;
	FS_LOG_INFO("forest-sim: "
	            << res.stats.trees << " trees, " << res.stats.saplings
	            << " saplings, " << res.stats.shrubs << " shrubs, route "
	            << fmt("%.0f", res.path_length_m) << " m, "
	            << fmt("%.1f", res.duration_s) << " s, " << lidar.scanCount()
	            << " scans (setup " << fmt("%.1f", res.setup_wall_s) << " s)");

	io::RawlogWriter rawlog(out("run.rawlog"), o.output.compress_level);
	std::unique_ptr<BagWriter> bag;
	if (!req.bag_path.empty())
	{
		const auto parent = fs::path(req.bag_path).parent_path();
		if (!parent.empty()) core::ensureDirectory(parent.string());
		bag =
		    std::make_unique<BagWriter>(req.bag_path, o.output.bag_compression);
		bag->writeStaticTransforms(sc.body().startTime(), o);
	}

	// IMU and GNSS records are merged by time around the scans: into the
	// rawlog by timestamp (a scan's is its first firing), into the bag by
	// receive time (a cloud is published once its sweep is complete).
	size_t ri = 0, rg = 0, bi = 0, bg = 0;
	auto flushRawlog = [&](double t_limit)
	{
		while (true)
		{
			const bool has_i = ri < imu.size() && imu[ri].t <= t_limit;
			const bool has_g = rg < gnss.size() && gnss[rg].t <= t_limit;
			if (!has_i && !has_g) break;
			if (has_i && (!has_g || imu[ri].t <= gnss[rg].t))
				rawlog.write(*toObservation(imu[ri++], o.imu));
			else
				rawlog.write(*toObservation(gnss[rg++], o.gnss));
		}
	};
	auto flushBag = [&](double t_limit)
	{
		if (!bag) return;
		while (true)
		{
			const bool has_i = bi < imu.size() && imu[bi].t <= t_limit;
			const bool has_g = bg < gnss.size() && gnss[bg].t <= t_limit;
			if (!has_i && !has_g) break;
			if (has_i && (!has_g || imu[bi].t <= gnss[bg].t))
				bag->writeImu(imu[bi++], o.imu);
			else
				bag->writeGnss(gnss[bg++]);
		}
	};

	core::ProgressReporter progress(req.progress_tty);
	const double period = 1.0 / o.lidar.rate_hz;
	for (size_t k = 0; k < lidar.scanCount(); k++)
	{
		const double t_k = lidar.scanTime(k);
		flushRawlog(t_k + 1e-9);
		// Relative time from the index: exact, unlike a difference of
		// absolute stamps near 1.7e9 s.
		const ScanFault fault = scanFault(o.faults, k * period, period);
		if (fault != ScanFault::Drop)
		{
			const double c0 = wallNow();
			const auto scan = lidar.scan(k);
			res.lidar_wall_s += wallNow() - c0;
			applyScanFault(fault, *scan);
			for (int r = 0; r < scan->rangeImage.rows(); r++)
				for (int c = 0; c < scan->rangeImage.cols(); c++)
					res.points += scan->rangeImage(r, c) != 0;
			const int copies = fault == ScanFault::Duplicate ? 2 : 1;
			for (int i = 0; i < copies; i++)
			{
				rawlog.write(*scan);
				if (bag)
				{
					flushBag(t_k + period - 1e-9);
					bag->writeScan(*scan, t_k + period);
				}
				res.scans++;
			}
		}
		progress.update(res.scans, double(k + 1) / lidar.scanCount(),
		                t_k - sc.body().startTime());
	}
	flushRawlog(1e300);
	flushBag(1e300);
	progress.finish();
	rawlog.close();
	res.outputs.push_back(out("run.rawlog"));
	if (bag)
	{
		bag->close();
		res.outputs.push_back(req.bag_path);
	}
	res.imu = imu.size();
	res.gnss = gnss.size();

	io::writeTum(out("gt_trajectory.tum"),
	             sc.lidarTrajectory(o.output.gt_rate_hz));
	res.outputs.push_back(out("gt_trajectory.tum"));

	const Eigen::Isometry3d& M = sc.mapFromWorld();
	core::writeFileAtomically(
	    out("gt_trees.csv"),
	    [&](std::ostream& f)
	    {
		    f << "id,x,y,z_ground,dbh_m,height_m,lean_deg,sapling\n";
		    char line[256];
		    for (const auto& t : sc.scene().trees)
		    {
			    // x, y: stem axis at breast height (where DBH is measured).
			    const Eigen::Vector3d b =
			        M * Eigen::Vector3d(t.breast_xy.x(), t.breast_xy.y(),
			                            t.ground.z() + 1.3);
			    const Eigen::Vector3d g = M * t.ground;
			    std::snprintf(line, sizeof(line),
			                  "%d,%.4f,%.4f,%.4f,%.4f,%.2f,%.2f,%d\n", t.id,
			                  b.x(), b.y(), g.z(), t.dbh_m, t.height_m,
			                  t.lean_deg, t.sapling ? 1 : 0);
			    f << line;
		    }
	    });
	res.outputs.push_back(out("gt_trees.csv"));

	core::writeFileAtomically(
	    out("gnss_map.csv"),
	    [&](std::ostream& f)
	    {
		    f << "t,x,y,z,quality,sigma_h_m,sigma_v_m,sky_fraction\n";
		    char line[256];
		    for (const auto& g : gnss)
		    {
			    if (g.quality == 0) continue;
			    const Eigen::Vector3d p = M * g.enu_measured;
			    std::snprintf(line, sizeof(line),
			                  "%.6f,%.4f,%.4f,%.4f,%d,%.3f,%.3f,%.3f\n", g.t,
			                  p.x(), p.y(), p.z(), g.quality, g.sigma_h_m,
			                  g.sigma_v_m, g.sky_fraction);
			    f << line;
			    res.gnss_fixes++;
		    }
	    });
	res.outputs.push_back(out("gnss_map.csv"));

	res.total_wall_s = wallNow() - wall0;
	const std::string ini = scenarioIni(sc, res);
	core::writeFileAtomically(out("scenario.ini"),
	                          [&](std::ostream& f) { f << ini; });
	res.outputs.push_back(out("scenario.ini"));
	return res;
}

}  // namespace forest_slam::sim
