#pragma once
// Poses with the timestamp of the instant they describe (for a scan: its
// deskew reference time, never the arrival time).
#include <Eigen/Geometry>

#include <vector>

namespace forest_slam::core
{
struct StampedPose
{
	double t_s = 0;	 ///< UNIX seconds
	Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();	 ///< sensor -> map
	EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

using Trajectory = std::vector<StampedPose, Eigen::aligned_allocator<StampedPose>>;

/** Pose at time t by linear/slerp interpolation of a time-sorted trajectory;
 * returns false if t is outside [front.t, back.t] (beyond `tolerance_s`). */
bool interpolatePose(const Trajectory& traj, double t_s, Eigen::Isometry3d& out,
					 double tolerance_s = 1e-6);

/** Interpolates between two isometries with slerp on the rotation. */
Eigen::Isometry3d interpolateIsometry(
	const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double alpha);

}  // namespace forest_slam::core
