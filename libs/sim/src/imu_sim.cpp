#include <forest_slam/sim/imu_sim.h>

#include <mrpt/core/Clock.h>

#include <cmath>

namespace forest_slam::sim
{
std::vector<ImuSample> simulateImu(const BodyTrajectory& body,
                                   const ImuOptions& o, Rng& rng)
{
	const Eigen::Isometry3d T_bi = o.mount.toIsometry();  // imu -> body
	const Eigen::Vector3d lever = T_bi.translation();
	const Eigen::Matrix3d R_bi = T_bi.linear();
	const Eigen::Vector3d g(0, 0, -o.gravity_mps2);
	const double dt = 1.0 / o.rate_hz;
	// Continuous-time densities to discrete standard deviations.
	const double sg = o.gyro_noise_density * std::sqrt(o.rate_hz);
	const double sa = o.accel_noise_density * std::sqrt(o.rate_hz);
	const double wg = o.gyro_bias_walk * std::sqrt(dt);
	const double wa = o.accel_bias_walk * std::sqrt(dt);
	auto randVec = [&](double s) -> Eigen::Vector3d
	{
		const double x = rng.normal(), y = rng.normal(), z = rng.normal();
		return Eigen::Vector3d(x, y, z) * s;
	};
	Eigen::Vector3d bg = randVec(o.gyro_bias_sigma_rad_s);
	Eigen::Vector3d ba = randVec(o.accel_bias_sigma_mps2);

	std::vector<ImuSample> out;
	const double t0 = body.startTime(), t1 = body.endTime();
	const long n =
	    static_cast<long>(std::floor((t1 - t0) * o.rate_hz + 1e-9)) + 1;
	out.reserve(n);
	for (long i = 0; i < n; i++)
	{
		const double t = t0 + i * dt;
		const BodyState s = body.state(t);
		// Acceleration of the IMU point: a + R (dw x r + w x (w x r)).
		const Eigen::Vector3d a_imu =
		    s.a + s.R * (s.dw_body.cross(lever) +
		                 s.w_body.cross(s.w_body.cross(lever)));
		const Eigen::Matrix3d R_wi = s.R * R_bi;
		ImuSample m;
		m.t = t;
		m.gyro_bias = bg;
		m.acc_bias = ba;
		m.gyro = R_bi.transpose() * s.w_body + bg + randVec(sg);
		m.acc = R_wi.transpose() * (a_imu - g) + ba + randVec(sa);
		out.push_back(m);
		bg += randVec(wg);
		ba += randVec(wa);
	}
	return out;
}

mrpt::obs::CObservationIMU::Ptr toObservation(const ImuSample& s,
                                              const ImuOptions& o)
{
	auto obs = mrpt::obs::CObservationIMU::Create();
	obs->sensorLabel = "imu";
	obs->timestamp = mrpt::Clock::fromDouble(s.t);
	obs->sensorPose = o.mount.toCPose3D();
	obs->set(mrpt::obs::IMU_X_ACC, s.acc.x());
	obs->set(mrpt::obs::IMU_Y_ACC, s.acc.y());
	obs->set(mrpt::obs::IMU_Z_ACC, s.acc.z());
	obs->set(mrpt::obs::IMU_WX, s.gyro.x());
	obs->set(mrpt::obs::IMU_WY, s.gyro.y());
	obs->set(mrpt::obs::IMU_WZ, s.gyro.z());
	return obs;
}

}  // namespace forest_slam::sim
