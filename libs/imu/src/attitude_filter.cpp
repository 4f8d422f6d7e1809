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
	FS_LOAD(c, s, standstill_bias);
	FS_LOAD(c, s, standstill_gyro_deg_s);
	FS_LOAD(c, s, standstill_accel_mps2);
	FS_LOAD(c, s, standstill_max_bias_deg_s);
	FS_LOAD(c, s, standstill_window_samples);
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
	if (!(standstill_gyro_deg_s > 0) || !(standstill_accel_mps2 > 0) ||
	    !(standstill_max_bias_deg_s >= 0))
		throw core::ConfigError(where +
		                        "standstill_gyro_deg_s and "
		                        "standstill_accel_mps2 must be > 0, "
		                        "standstill_max_bias_deg_s >= 0");
	if (standstill_window_samples < 1)
		throw core::ConfigError(where +
		                        "standstill_window_samples must be >= 1");
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
	c.write(s, "standstill_bias", standstill_bias);
	c.write(s, "standstill_gyro_deg_s", standstill_gyro_deg_s);
	c.write(s, "standstill_accel_mps2", standstill_accel_mps2);
	c.write(s, "standstill_max_bias_deg_s", standstill_max_bias_deg_s);
	c.write(s, "standstill_window_samples", standstill_window_samples);
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

void AttitudeFilter::trackRest(const Eigen::Vector3d& gyro,
                               const Eigen::Vector3d& acc)
{
	if (!rest_) return;
	if (!o_.standstill_bias || !gyro.allFinite() || !acc.allFinite())
	{
		rest_ = false;
		return;
	}
	constexpr double kDeg = M_PI / 180;
	// Tested by windows of samples, whose means show the start of a slow
	// motion (a robot's speed ramp, its vibration growing with the speed)
	// above the noise; a window that moved is left out, so the estimate
	// is made of samples at rest only (sample by sample, 3 deg/s let the
	// robot's first half second of driving into it: its map turned by
	// 30 mdeg).
	win_gyro_sum_ += gyro, win_acc_sum_ += acc, win_n_++;
	if (win_n_ >= o_.standstill_window_samples)
	{
		const Eigen::Vector3d g = win_gyro_sum_ / win_n_,
		                      a = win_acc_sum_ / win_n_;
		if (rest_n_ > 0 &&
		    ((g - rest_gyro_sum_ / rest_n_).norm() >
		         o_.standstill_gyro_deg_s * kDeg ||
		     (a - rest_acc_sum_ / rest_n_).norm() > o_.standstill_accel_mps2))
		{
			rest_ = false;  // moved: the estimate so far stays
			return;
		}
		rest_gyro_sum_ += win_gyro_sum_, rest_acc_sum_ += win_acc_sum_;
		rest_n_ += win_n_;
		win_gyro_sum_.setZero(), win_acc_sum_.setZero(), win_n_ = 0;
	}
	// Until the first window is complete (the first scan's deskew may come
	// before), the samples so far.
	const Eigen::Vector3d mean = rest_n_ > 0
	                                 ? Eigen::Vector3d(rest_gyro_sum_ / rest_n_)
	                                 : Eigen::Vector3d(win_gyro_sum_ / win_n_);
	if (mean.norm() <= o_.standstill_max_bias_deg_s * kDeg)
		bias_ = mean;
	else
		bias_.setZero();  // a slow turn, not a bias
}

void AttitudeFilter::update(const Eigen::Vector3d& gyro,
                            const Eigen::Vector3d& acc, double dt)
{
	trackRest(gyro, acc);
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
			// At rest the bias is the mean gyro (trackRest).
			if (!rest_) bias_ -= k * o_.ki * e * dt;
		}
	}
	q_ = (q_ * expQ(w * dt)).normalized();
}

}  // namespace forest_slam::imu
