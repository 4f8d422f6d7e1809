#pragma once
// One simulated run, top to bottom:
//   route (PathPlan) -> forest around it (buildScene) -> C2 motion on the
//   terrain (planBodyTrajectory) -> IMU and GNSS streams -> one lidar scan
//   per revolution, written in time order with the IMU and GNSS records to
//   DIR/run.rawlog (and optionally a ROS1 bag), then the ground truth files.
// Frames: "world" is a local ENU frame whose origin is the ground at the
// start (the geodetic origin of [gnss]); "map" is the project convention:
// origin at the first lidar position, x along the first lidar heading (yaw
// only), z up. Every ground-truth file is in the map frame.
#include <forest_slam/core/trajectory.h>
#include <forest_slam/sim/body_trajectory.h>
#include <forest_slam/sim/motion_planner.h>
#include <forest_slam/sim/options.h>
#include <forest_slam/sim/scene_builder.h>

#include <string>
#include <vector>

namespace forest_slam::sim
{
/** The generated world and motion (no sensor data yet). */
class Scenario
{
   public:
	/** Uses o.effective() (noise switch applied). */
	explicit Scenario(const SimOptions& o);

	const SimOptions& options() const { return o_; }
	const PathPlan& path() const { return path_; }
	const Scene& scene() const { return scene_; }
	const World& world() const { return *scene_.world; }
	const BodyTrajectory& body() const { return body_; }

	/** map <- world */
	const Eigen::Isometry3d& mapFromWorld() const { return map_from_world_; }
	/** Lidar pose (lidar -> map) at time t. */
	Eigen::Isometry3d lidarPoseInMap(double t) const;
	/** Lidar poses at `rate_hz` over the whole run, map frame. */
	core::Trajectory lidarTrajectory(double rate_hz) const;
	/** Seeds of the sensor streams, derived from the run seed. */
	uint64_t lidarSeed() const;
	uint64_t imuSeed() const;
	uint64_t gnssSeed() const;

   private:
	SimOptions o_;
	PathPlan path_;
	Scene scene_;
	BodyTrajectory body_;
	Eigen::Isometry3d map_from_world_;
	EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

struct RunRequest
{
	std::string out_dir;
	std::string bag_path;   ///< empty: no bag
	int progress_tty = -1;  ///< -1 auto, 0 log lines, 1 bar
};

struct RunResult
{
	size_t scans = 0, imu = 0, gnss = 0, gnss_fixes = 0;
	uint64_t points = 0;
	double duration_s = 0;  ///< of data
	double path_length_m = 0;
	double setup_wall_s = 0;  ///< world + motion generation
	double lidar_wall_s = 0;  ///< ray casting only
	double total_wall_s = 0;
	SceneStats stats;
	std::vector<std::string> outputs;
	double scansPerSecond() const
	{
		return lidar_wall_s > 0 ? scans / lidar_wall_s : 0;
	}
};

/** Generates everything into req.out_dir (created if missing):
 * run.rawlog, gt_trajectory.tum, gt_trees.csv, gnss_map.csv, scenario.ini
 * and req.bag_path if given. All outputs are written atomically. */
RunResult runSimulation(const SimOptions& o, const RunRequest& req);

/** The text of scenario.ini: effective options + [ground_truth]. */
std::string scenarioIni(const Scenario& sc, const RunResult& r);

}  // namespace forest_slam::sim
