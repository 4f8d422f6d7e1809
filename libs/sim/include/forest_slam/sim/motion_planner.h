#pragma once
// Where and how the sensor rig moves. Two steps because the world depends on
// the path (no tree on the path, world bounds) and the motion depends on the
// world (terrain height and slope):
//   1. PathPlan::make: the horizontal route, starting at the world origin.
//      handheld: a closed C2 curve, a big irregular loop then a small inner
//      loop (out and back on two parallel lines), back to the start;
//      robot: straight legs between jittered corners of a rectangle, several
//      laps, with stops and in-place turns at the corners.
//   2. planBodyTrajectory: speed profile, gait or terrain attitude and
//      vibration, sampled on the knots of the BodyTrajectory spline. Both
//      scenarios start and end at rest at exactly the same pose.
#include <forest_slam/sim/body_trajectory.h>
#include <forest_slam/sim/options.h>
#include <forest_slam/sim/random.h>
#include <forest_slam/sim/terrain.h>

#include <Eigen/Core>

#include <vector>

namespace forest_slam::sim
{
class PathPlan
{
   public:
	static PathPlan make(const MotionOptions& o, Rng& rng);

	MotionType type() const { return type_; }
	double length() const { return length_; }
	/** Points every `spacing_m` from the start to the end of the route. */
	std::vector<Eigen::Vector2d> sample(double spacing_m) const;
	/** Position and unit tangent at arc length s in [0, length]. */
	Eigen::Vector2d point(double s) const;
	Eigen::Vector2d tangent(double s) const;
	/** Robot: corners in driving order, first and last = start. */
	const std::vector<Eigen::Vector2d>& waypoints() const { return waypoints_; }

   private:
	MotionType type_ = MotionType::Handheld;
	// Handheld: closed uniform cubic B-spline; arc length table.
	std::vector<Eigen::Vector2d> ctrl_;
	std::vector<double> table_u_, table_s_;
	// Robot: polyline.
	std::vector<Eigen::Vector2d> waypoints_;
	std::vector<double> cum_len_;
	double length_ = 0;

	double paramAt(double s) const;
	Eigen::Vector2d curve(double u, Eigen::Vector2d* du = nullptr) const;
};

/** Samples the motion on spline knots from t0 (start of the start pause). */
BodyTrajectory planBodyTrajectory(const PathPlan& path, const MotionOptions& o,
                                  const Terrain& terrain, double t0, Rng& rng);

}  // namespace forest_slam::sim
