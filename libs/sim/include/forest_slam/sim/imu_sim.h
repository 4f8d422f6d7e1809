#pragma once
// IMU readings derived from the ground-truth spline: specific force
// f = R_imu^T (a_imu - g) with g = (0, 0, -gravity), including the lever arm
// of the IMU on the body, and angular rate w_imu = R_bi^T w_body; then white
// noise, a random initial bias and a bias random walk per axis.
#include <forest_slam/sim/body_trajectory.h>
#include <forest_slam/sim/options.h>
#include <forest_slam/sim/random.h>

#include <mrpt/obs/CObservationIMU.h>

#include <vector>

namespace forest_slam::sim
{
struct ImuSample
{
	double t = 0;
	Eigen::Vector3d gyro, acc;  ///< measured (rad/s, m/s^2), IMU frame
	Eigen::Vector3d gyro_bias, acc_bias;  ///< the biases inside them
};

/** Samples at t0 + i/rate over the trajectory domain. */
std::vector<ImuSample> simulateImu(const BodyTrajectory& body,
                                   const ImuOptions& o, Rng& rng);

mrpt::obs::CObservationIMU::Ptr toObservation(const ImuSample& s,
                                              const ImuOptions& o);

}  // namespace forest_slam::sim
