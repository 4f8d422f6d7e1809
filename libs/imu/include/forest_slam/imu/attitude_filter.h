#pragma once
// Attitude from gyro + accelerometer: a complementary filter (Mahony) with
// gyro-bias estimation. The accelerometer pulls roll and pitch towards
// gravity with gain kp (and kp/10 when the specific force is far from g, i.e.
// the sensor accelerates); the integral term ki learns the gyro bias. Yaw is
// not observable from gravity: it stays the integrated gyro.
//
// The gravity reference is the specific force low-passed in the (estimated)
// world frame over accel_lowpass_s, not each sample's direction: a walking
// gait bobs the rig by several m/s^2 vertically, and its small forward
// accelerations are correlated with that bob, so the mean of per-sample
// *directions* leans forward by several degrees (measured: 5 deg RMS tilt
// error on the forest-sim handheld scenario) while the mean specific-force
// *vector* is vertical within 0.1 deg.
#include <mrpt/config/CLoadableOptions.h>

#include <Eigen/Geometry>

namespace forest_slam::imu
{
struct AttitudeOptions : public mrpt::config::CLoadableOptions
{
	double kp = 0.2;   ///< proportional gain [1/s]: time constant ~ 1/kp
	double ki = 0.01;  ///< integral gain (gyro bias) [1/s^2]
	/** Specific force this far from g [m/s^2]: the sensor accelerates, the
	 * gravity correction is weakened tenfold. */
	double accel_tolerance = 1.0;
	/** Time constant of the world-frame low-pass of the specific force that
	 * serves as the gravity reference [s] (0: each sample on its own). Longer
	 * than a gait cycle (~0.5 s). */
	double accel_lowpass_s = 0.5;
	double gravity = 9.80665;
	/** The filter levels itself with the mean specific force of this many
	 * first samples (one noisy sample would tilt the whole map). */
	int init_samples = 20;
	/** The gyro bias from the start at rest: while the mean of every
	 * window of standstill_window_samples samples since the first stays
	 * within standstill_gyro_deg_s and standstill_accel_mps2 of the mean
	 * so far, the bias is that mean gyro (the integral term takes over once
	 * the sensor moves; the window that moved is left out). Yaw's bias is
	 * not observable from gravity: left at 0, it twisted the first scan's
	 * deskew, which is the map's origin (forest-sim handheld: the map
	 * rotated by ~10 mdeg). A mean above standstill_max_bias_deg_s is
	 * taken for a slow turn, not a bias: no estimate. Off by default: no
	 * gain measured on forest-sim, whose yaw biases are small, and one
	 * world of six mapped 0.026 deg more rotated (doc/odometry.md). */
	bool standstill_bias = false;
	double standstill_gyro_deg_s = 0.5;
	double standstill_accel_mps2 = 0.1;
	double standstill_max_bias_deg_s = 2.0;
	int standstill_window_samples = 20;

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& section) const override;
};

class AttitudeFilter
{
   public:
	explicit AttitudeFilter(const AttitudeOptions& o = {}) : o_(o) {}
	const AttitudeOptions& options() const { return o_; }

	/** One sample taken dt seconds after the previous one. The mean of the
	 * first init_samples plausible accelerometer readings levels the filter
	 * (the gyro rotation meanwhile is neglected: a tenth of a second). */
	void update(const Eigen::Vector3d& gyro, const Eigen::Vector3d& acc,
	            double dt);

	bool initialised() const { return initialised_; }
	const Eigen::Quaterniond& attitude() const
	{
		return q_;
	}  ///< world <- sensor
	const Eigen::Vector3d& gyroBias() const { return bias_; }
	/** Whether every sample so far was at rest (standstill_bias). */
	bool atRestSinceStart() const { return rest_; }
	/** Samples the estimate at rest is made of. */
	int restSamples() const { return rest_n_; }

   private:
	AttitudeOptions o_;
	bool initialised_ = false;
	Eigen::Quaterniond q_ = Eigen::Quaterniond::Identity();
	Eigen::Vector3d bias_ = Eigen::Vector3d::Zero();
	Eigen::Vector3d init_sum_ = Eigen::Vector3d::Zero();
	Eigen::Vector3d force_world_lp_ = Eigen::Vector3d::Zero();
	int init_n_ = 0;
	// The start at rest: sums over its samples.
	bool rest_ = true;
	Eigen::Vector3d rest_gyro_sum_ = Eigen::Vector3d::Zero();
	Eigen::Vector3d rest_acc_sum_ = Eigen::Vector3d::Zero();
	int rest_n_ = 0;
	Eigen::Vector3d win_gyro_sum_ = Eigen::Vector3d::Zero();  ///< the window
	Eigen::Vector3d win_acc_sum_ = Eigen::Vector3d::Zero();
	int win_n_ = 0;
	void trackRest(const Eigen::Vector3d& gyro, const Eigen::Vector3d& acc);
};

}  // namespace forest_slam::imu
