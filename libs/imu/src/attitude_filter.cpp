#include <forest_slam/core/config.h>
#include <forest_slam/imu/attitude_filter.h>

#include <cmath>

namespace forest_slam::imu
{
void AttitudeOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                         const std::string& s)
{
	FS_LOAD(c, s, kp);
	FS_LOAD(c, s, ki);
	FS_LOAD(c, s, accel_tolerance);
	FS_LOAD(c, s, accel_lowpass_s);
	FS_LOAD(c, s, gravity);
	FS_LOAD(c, s, init_samples);
	const std::string where = core::configOrigin(c) + ": [" + s + "] ";
	if (!(kp >= 0) || !(ki >= 0))
		throw core::ConfigError(where + "kp and ki must be >= 0");
	if (!(accel_lowpass_s >= 0))
		throw core::ConfigError(where + "accel_lowpass_s must be >= 0");
	if (!(accel_tolerance > 0) || !(gravity > 0))
		throw core::ConfigError(where +
		                        "accel_tolerance and gravity must be > 0");
	if (init_samples < 1)
		throw core::ConfigError(where + "init_samples must be >= 1");
}

void AttitudeOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                       const std::string& s) const
{
	c.write(s, "kp", kp);
	c.write(s, "ki", ki);
	c.write(s, "accel_tolerance", accel_tolerance);
	c.write(s, "accel_lowpass_s", accel_lowpass_s);
	c.write(s, "gravity", gravity);
	c.write(s, "init_samples", init_samples);
}

namespace
{
Eigen::Quaterniond expQ(const Eigen::Vector3d& w)
{
	const double a = w.norm();
	if (a < 1e-12)
		return Eigen::Quaterniond(1, 0.5 * w.x(), 0.5 * w.y(), 0.5 * w.z())
		    .normalized();
	return Eigen::Quaterniond(Eigen::AngleAxisd(a, w / a));
}
}  // namespace

void AttitudeFilter::update(const Eigen::Vector3d& gyro,
                            const Eigen::Vector3d& acc, double dt)
{
	const double an = acc.norm();
	if (!initialised_)
	{
		if (!(an > 0.5 * o_.gravity && an < 1.5 * o_.gravity)) return;
		init_sum_ += acc;
		if (++init_n_ < o_.init_samples) return;
		// Level: the mean specific force is "up".
		q_ = Eigen::Quaterniond::FromTwoVectors(init_sum_.normalized(),
		                                        Eigen::Vector3d::UnitZ());
		force_world_lp_ = q_ * (init_sum_ / init_n_);
		initialised_ = true;
		return;
	}
	Eigen::Vector3d w = gyro - bias_;
	if (acc.allFinite())
	{
		// Low-pass the specific force in the world frame (see the header):
		// its mean over a gait cycle is gravity, its direction per sample
		// is not.
		const double a = o_.accel_lowpass_s > 0
		                     ? std::min(1.0, dt / o_.accel_lowpass_s)
		                     : 1.0;
		force_world_lp_ += a * (q_ * acc - force_world_lp_);
		const double fn = force_world_lp_.norm();
		if (fn > 1e-3)
		{
			// Error between the reference and "up", in the body frame.
			const Eigen::Vector3d e =
			    q_.conjugate() *
			    (force_world_lp_ / fn).cross(Eigen::Vector3d::UnitZ());
			const double k =
			    std::abs(fn - o_.gravity) < o_.accel_tolerance ? 1.0 : 0.1;
			w += k * o_.kp * e;
			bias_ -= k * o_.ki * e * dt;
		}
	}
	q_ = (q_ * expQ(w * dt)).normalized();
}

}  // namespace forest_slam::imu
