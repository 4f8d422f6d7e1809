#pragma once
// Attitude from gyro + accelerometer: a complementary filter (Mahony) with
// gyro-bias estimation. The accelerometer pulls roll and pitch towards
// gravity with gain kp (and kp/10 when the specific force is far from g, i.e.
// the sensor accelerates); the integral term ki learns the gyro bias. Yaw is
// not observable from gravity: it stays the integrated gyro.
#include <mrpt/config/CLoadableOptions.h>

#include <Eigen/Geometry>

namespace forest_slam::imu
{
struct AttitudeOptions : public mrpt::config::CLoadableOptions
{
	double kp = 0.5;   ///< proportional gain [1/s]: time constant ~ 1/kp
	double ki = 0.02;  ///< integral gain (gyro bias) [1/s^2]
	/** Specific force this far from g [m/s^2]: the sensor accelerates, the
	 * gravity correction is weakened tenfold. */
	double accel_tolerance = 1.0;
	double gravity = 9.80665;
	/** The filter levels itself with the mean specific force of this many
	 * first samples (one noisy sample would tilt the whole map). */
	int init_samples = 20;

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& section) const override;
};

class AttitudeFilter
{
   public:
	explicit AttitudeFilter(const AttitudeOptions& o = {}) : o_(o) {}

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

   private:
	AttitudeOptions o_;
	bool initialised_ = false;
	Eigen::Quaterniond q_ = Eigen::Quaterniond::Identity();
	Eigen::Vector3d bias_ = Eigen::Vector3d::Zero();
	Eigen::Vector3d init_sum_ = Eigen::Vector3d::Zero();
	int init_n_ = 0;
};

}  // namespace forest_slam::imu
