#include <forest_slam/core/trajectory.h>

#include <algorithm>

namespace forest_slam::core
{
Eigen::Isometry3d interpolateIsometry(
	const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double alpha)
{
	const Eigen::Quaterniond qa(a.linear()), qb(b.linear());
	Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
	out.linear() = qa.slerp(alpha, qb).toRotationMatrix();
	out.translation() =
		(1 - alpha) * a.translation() + alpha * b.translation();
	return out;
}

bool interpolatePose(const Trajectory& traj, double t, Eigen::Isometry3d& out,
					 double tol)
{
	if (traj.empty()) return false;
	if (t < traj.front().t_s - tol || t > traj.back().t_s + tol) return false;
	auto it = std::lower_bound(
		traj.begin(), traj.end(), t,
		[](const StampedPose& p, double v) { return p.t_s < v; });
	if (it == traj.begin())
	{
		out = it->pose;
		return true;
	}
	if (it == traj.end())
	{
		out = traj.back().pose;
		return true;
	}
	const auto& b = *it;
	const auto& a = *(it - 1);
	const double dt = b.t_s - a.t_s;
	const double alpha = dt > 0 ? (t - a.t_s) / dt : 0.0;
	out = interpolateIsometry(a.pose, b.pose, alpha);
	return true;
}

}  // namespace forest_slam::core
