#pragma once
// Levelling the map frame with gravity over a whole run. The map frame is
// levelled once, at the first scan, with the IMU attitude filter's "up";
// an accelerometer bias tilts that "up" (0.03 m/s^2 is 0.18 deg), and the
// odometry keeps the tilt for the whole run: 0.2-0.4 deg on the forest-sim
// runs, 40-85 cm of height error 100 m from the start. The bias is fixed in
// the sensor frame while the map's tilt is fixed in the map frame, so the
// "up" measured at keyframes of many headings tells the two apart.
#include <Eigen/Geometry>

#include <optional>
#include <vector>

namespace forest_slam::loop
{
struct LevellingOptions
{
	/** Error of one keyframe's "up" (attitude filter while moving) [rad]. */
	double up_sigma_rad = 0.5 * M_PI / 180;
	/** Prior of the tilt the accelerometer bias causes, per axis of the
	 * sensor frame [rad]: holds it where the headings cannot (a straight
	 * path), so the map then takes the mean "up" of the run. */
	double bias_sigma_rad = 0.5 * M_PI / 180;
	size_t min_keyframes = 20;
};

struct Levelling
{
	bool ok = false;
	/** Rotation about the map origin that makes gravity the map's z. */
	Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
	double tilt_deg = 0;  ///< angle of R
	/** The tilt of "up" the bias causes, in the sensor frame [deg]. */
	Eigen::Vector3d bias_deg = Eigen::Vector3d::Zero();
	size_t used = 0, rejected = 0;  ///< keyframes (3-sigma outliers)
	double residual_rms_deg = 0;
};

/** From keyframe orientations (map frame) and the "up" measured in each
 * keyframe's frame (unit vectors; missing where the IMU did not cover it).
 * Least squares on the horizontal part of R_k up_k = tilt + R_k bias, once
 * more without the residuals beyond 3 RMS. */
Levelling estimateLevelling(
    const std::vector<Eigen::Matrix3d>& R_map_keyframe,
    const std::vector<std::optional<Eigen::Vector3d>>& up_in_keyframe,
    const LevellingOptions& o = {});

}  // namespace forest_slam::loop
