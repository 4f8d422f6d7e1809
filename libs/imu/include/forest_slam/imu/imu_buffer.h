#pragma once
// IMU samples of the current stretch of time, expressed in the vehicle
// (body) frame the sensors are mounted on, with the two things the odometry
// asks of them: the rotation of the body between two instants (gyro
// integration, bias removed) and the direction of gravity (attitude filter,
// see attitude_filter.h). The caller rotates them into the lidar frame.
#include <forest_slam/imu/attitude_filter.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <deque>
#include <iterator>
#include <optional>
#include <string>

namespace forest_slam::imu
{
struct ImuSample
{
	double t_s = 0;
	Eigen::Vector3d gyro = Eigen::Vector3d::Zero();  ///< rad/s, body frame
	Eigen::Vector3d acc =
	    Eigen::Vector3d::Zero();  ///< m/s^2 specific force, body frame
};

/** What the accelerometer says about the motion over [t0, t1], in the body
 * frame at t0, with a(u) = R_t0_u f(u) + gravity_t0 the acceleration of the
 * body (f the specific force, gravity_t0 the gravity vector in the t0
 * frame): dv = integral of a, dp = double integral (the displacement at zero
 * initial velocity), and moment = integral of a(u) (u - t0) du / (t1 - t0),
 * which turns a mean velocity over the interval into the velocity at t1:
 * v(t1) = (p(t1) - p(t0)) / (t1 - t0) + moment. */
struct AccelIntegral
{
	Eigen::Vector3d dv = Eigen::Vector3d::Zero();
	Eigen::Vector3d dp = Eigen::Vector3d::Zero();
	Eigen::Vector3d moment = Eigen::Vector3d::Zero();
};

class ImuBuffer
{
   public:
	explicit ImuBuffer(const AttitudeOptions& o = {}) : kp_(o.kp), filter_(o) {}

	/** Adds a sample given in the body frame. Returns false (and keeps
	 * nothing) for a non-finite sample or one not after the previous sample:
	 * the caller counts and reports those. */
	bool add(double t_s, const Eigen::Vector3d& gyro,
	         const Eigen::Vector3d& acc);

	bool empty() const { return samples_.empty(); }
	double latestTime() const
	{
		return samples_.empty() ? -1e300 : samples_.back().s.t_s;
	}
	/** True when samples exist at or before t0 and at or after t1, with no
	 * gap longer than max_gap_s in between. */
	bool covers(double t0_s, double t1_s, double max_gap_s = 0.05) const;

	/** Rotation of the body frame at t1 expressed in the frame at t0
	 * (R_t0_t1), by integrating bias-corrected gyro rates. Requires covers().
	 */
	Eigen::Quaterniond rotationBetween(double t0_s, double t1_s) const;

	/** Integrates the accelerometer over [t0, t1] (see AccelIntegral);
	 * gravity_t0 is the gravity vector (pointing down, m/s^2) in the body
	 * frame at t0. Trapezoid steps between samples, the rotation from the
	 * gyro. Requires covers(). */
	AccelIntegral integrateAcceleration(
	    double t0_s, double t1_s, const Eigen::Vector3d& gravity_t0) const;

	/** Gravity-aligned attitude (world <- body) from the filter at the
	 * latest sample at or before t (or, before the filter levelled itself,
	 * its first levelled attitude carried back with the gyro); yaw is free
	 * and meaningless. False for 2/kp seconds (at most 2 s) after a gap in
	 * the samples, while the filter settles. */
	bool attitudeAt(double t_s, Eigen::Quaterniond& q) const;
	/** Gravity's "up" in a sensor frame mounted with R_body_sensor on the
	 * body, from attitudeAt(t) (none when that is false). */
	std::optional<Eigen::Vector3d> upAt(
	    double t_s, const Eigen::Matrix3d& R_body_sensor) const;
	const AttitudeFilter& filter() const { return filter_; }

	/** Drops samples older than t (keeps one at or before t). */
	void pruneBefore(double t_s);

   private:
	struct Entry
	{
		ImuSample s;
		Eigen::Quaterniond attitude;  ///< after this sample
		Eigen::Vector3d bias;         ///< gyro bias after this sample
		bool levelled = false;        ///< the filter was initialised
		bool settling = false;        ///< shortly after a gap: not trusted
	};
	/** Longest step integrated by the filter; a longer one is a gap. */
	static constexpr double kMaxStep_s = 0.1;
	double settle_until_s_ = -1e300;
	std::deque<Entry> samples_;
	/** The last sample at or before t, or the first one when all are after
	 * t; samples_ must not be empty. */
	std::deque<Entry>::const_iterator atOrBefore(double t) const
	{
		auto it = std::upper_bound(samples_.begin(), samples_.end(), t,
		                           [](double v, const Entry& e)
		                           { return v < e.s.t_s; });
		return it == samples_.begin() ? it : std::prev(it);
	}
	double kp_;
	AttitudeFilter filter_;
};

}  // namespace forest_slam::imu
