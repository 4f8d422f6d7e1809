#pragma once
// Where the lidar alone cannot be trusted, the motion model (IMU rotation +
// constant velocity) carries the pose (doc/reliability.md):
// - degenerate places (an open field, a straight trail): the registration
//   has no information along some directions, and whatever it returns there
//   is noise that the constant-velocity model would then carry on. The
//   estimate keeps the registration only along the directions the geometry
//   constrains and the prediction along the others ("solution remapping",
//   Zhang, Kaess & Singh, ICRA 2016);
// - gaps in the scans: the prediction bends with the IMU's turn.
#include <Eigen/Geometry>

#include <deque>
#include <functional>
#include <optional>

namespace forest_slam::odometry
{
/** `information` (6x6, [rotation (rad), translation (m)] as
 * RegistrationResult::information) with the rotation expressed as the
 * displacement it causes at `lever_arm_m` ([L*rotation, translation]): in
 * radians a rotation's information is the translation's times the squared
 * range, so the eigenvalues of the raw matrix compare metres with radians
 * and in a forest at 10-60 m range every translation looked "weak". */
Eigen::Matrix<double, 6, 6> scaledInformation(
    const Eigen::Matrix<double, 6, 6>& information, double lever_arm_m);

/** `estimate` with its difference from `predicted` projected onto the
 * eigenvectors of scaledInformation(information, lever_arm_m) whose
 * eigenvalue is at least `ratio` times the largest. Returns `estimate`
 * when no direction is weak. `weak_directions` (optional) gets how many
 * were removed. */
Eigen::Isometry3d remapDegenerate(
    const Eigen::Isometry3d& predicted, const Eigen::Isometry3d& estimate,
    const Eigen::Matrix<double, 6, 6>& information, double lever_arm_m,
    double ratio, int* weak_directions = nullptr);

/** Motion from t0 to t1 across a gap in the scans (t1 - t0 several scan
 * periods): `velocity` (the relative motion over one `period_s`, body frame)
 * is applied period by period, each step's rotation replaced by the IMU's
 * (`rotation(a, b)`: body at b in the frame at a), so the path bends with
 * the measured turn. */
Eigen::Isometry3d predictAcrossGap(
    const Eigen::Isometry3d& velocity, double period_s, double t0_s,
    double t1_s,
    const std::function<Eigen::Matrix3d(double, double)>& rotation);

/** A pose of the recent track: time, lidar position (map frame), heading
 * (horizontal direction of the lidar's x axis, rad) and whether the
 * registration constrained it in every direction. */
struct TrackPoint
{
	double t_s = 0;
	Eigen::Vector3d p = Eigen::Vector3d::Zero();
	double heading_rad = 0;
	bool constrained = false;
};

/** Heading of a lidar orientation: the horizontal direction of its x axis
 * (of its y axis when x points nearly up or down). */
double headingOf(const Eigen::Matrix3d& R);

/** Translation from t0_s to t1_s through a degenerate stretch: the mean
 * velocity over the last `window_s` of constrained poses of `track` (a
 * walking gait surges and bobs by 5 % and 0.5 m/s from scan to scan; the
 * chord over a gait cycle does not), held in the heading frame and turned
 * with the heading: a line fitted to the headings of the last `window_s` of
 * the track and `heading_t1` (the IMU-carried heading at t1), evaluated in
 * the middle of the step. Empty when the constrained poses span less than
 * half the window. */
std::optional<Eigen::Vector3d> meanVelocityStep(
    const std::deque<TrackPoint>& track, double window_s, double t0_s,
    double t1_s, double heading_t1);

}  // namespace forest_slam::odometry
