#pragma once
// A reference position track (GNSS fixes already expressed in the map frame)
// read from either a TUM file or a CSV with columns t,x,y,z.
#include <Eigen/Core>

#include <string>
#include <vector>

namespace forest_slam::eval
{
struct PositionFix
{
	double t_s = 0;
	Eigen::Vector3d p = Eigen::Vector3d::Zero();
};
using PositionTrack = std::vector<PositionFix>;

/** Format by content: if the first line that is not blank or '#' contains a
 * comma, the file is CSV with a header naming columns t,x,y,z (others are
 * ignored); otherwise it is TUM ("t x y z qx qy qz qw", orientation
 * ignored). Times must not go backwards. Throws naming file and line. */
PositionTrack readPositionTrack(const std::string& path);

}  // namespace forest_slam::eval
