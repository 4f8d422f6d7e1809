#pragma once
// The ground-truth motion of the vehicle (body) frame: six channels (x, y, z,
// yaw, pitch, roll) each a uniform cubic B-spline in time. A cubic B-spline
// is C2, so position, velocity, acceleration, attitude, angular rate and
// angular acceleration are all exact and continuous: the simulated IMU is the
// derivative of the very poses written to gt_trajectory.tum.
#include <Eigen/Geometry>

#include <array>
#include <vector>

namespace forest_slam::sim
{
struct BodyState
{
	Eigen::Vector3d p, v, a;  ///< world frame
	Eigen::Matrix3d R;        ///< body -> world
	Eigen::Vector3d w_body;   ///< angular rate in the body frame [rad/s]
	Eigen::Vector3d dw_body;  ///< its time derivative [rad/s^2]
};

/** R = Rz(yaw) * Ry(pitch) * Rx(roll). */
Eigen::Matrix3d rotationYPR(double yaw, double pitch, double roll);

class BodyTrajectory
{
   public:
	using Sample = std::array<double, 6>;  ///< x y z yaw pitch roll
	BodyTrajectory() = default;
	/** `ctrl[k]` is the control point of knot time t0 + (k-1)*dt; the curve
	 * is defined on [t0, t0 + (ctrl.size()-3)*dt]. Where four consecutive
	 * control points are equal the curve equals them exactly (rest). */
	BodyTrajectory(double t0, double dt, std::vector<Sample> ctrl);

	double startTime() const { return t0_; }
	double endTime() const
	{
		return t0_ + (static_cast<double>(ctrl_.size()) - 3) * dt_;
	}
	double knotSpacing() const { return dt_; }

	/** Channels and their first and second time derivatives at t (clamped
	 * to the domain). */
	void channels(double t, Sample& val, Sample* d1 = nullptr,
	              Sample* d2 = nullptr) const;
	/** body -> world */
	Eigen::Isometry3d pose(double t) const;
	BodyState state(double t) const;

   private:
	double t0_ = 0, dt_ = 0.01;
	std::vector<Sample> ctrl_;
};

}  // namespace forest_slam::sim
