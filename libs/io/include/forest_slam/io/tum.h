#pragma once
// TUM RGB-D trajectory format: "t x y z qx qy qz qw" per line, '#' comments.
#include <forest_slam/core/trajectory.h>

#include <string>

namespace forest_slam::io
{
/** Throws std::runtime_error naming file and line on any malformed line,
 * non-finite value or time going backwards. */
core::Trajectory readTum(const std::string& path);
/** Atomic write, 9 decimals for time, 6 for metres, 9 for quaternions. */
void writeTum(const std::string& path, const core::Trajectory& traj);

/** KITTI odometry poses: per pose one line with the 3x4 matrix [R | t]
 * row-major (12 numbers), in the trajectory's frame; no timestamps (they are
 * the same lines' times in the TUM file). Atomic write. */
void writeKitti(const std::string& path, const core::Trajectory& traj);

}  // namespace forest_slam::io
