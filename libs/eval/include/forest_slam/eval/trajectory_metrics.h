#pragma once
// Trajectory metrics: ATE (raw and SE(3)-aligned), KITTI-style RPE, vertical
// drift, return-to-start error (paper Table 5) and drift against GNSS every
// 10 s (paper Table 6). Definitions: doc/evaluation.md.
#include <forest_slam/core/trajectory.h>
#include <forest_slam/eval/position_track.h>
#include <forest_slam/eval/stats.h>

#include <vector>

namespace forest_slam::eval
{
/** Ground truth and estimate at the same instant (an estimate's stamp). */
struct PosePair
{
	double t_s = 0;
	Eigen::Isometry3d gt = Eigen::Isometry3d::Identity();
	Eigen::Isometry3d est = Eigen::Isometry3d::Identity();
	EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};
using PosePairs = std::vector<PosePair, Eigen::aligned_allocator<PosePair>>;

struct AssociationOptions
{
	/** An estimate stamp whose bracketing GT samples are further apart than
	 * this is not associated: interpolating across a GT hole would invent
	 * ground truth. */
	double max_gt_gap_s = 1.0;
};

struct Association
{
	PosePairs pairs;
	size_t est_outside_gt = 0;  ///< estimate stamps outside the GT time span
	size_t est_in_gt_gap = 0;   ///< inside the span but in a GT gap
};

/** Every estimate pose is paired with the GT interpolated at its stamp
 * (core::interpolatePose: linear position, slerp rotation). Throws
 * std::runtime_error if no pose can be associated (no time overlap). */
Association associateByInterpolation(const core::Trajectory& gt,
                                     const core::Trajectory& est,
                                     const AssociationOptions& opts = {});

/** Cumulative 3D path length of the GT along the pairs: out[i] is the
 * distance travelled from pairs[0] to pairs[i]. */
std::vector<double> gtDistanceTravelled(const PosePairs& pairs);

/** Least-squares rigid transform (no scale) T minimising
 * sum |dst_i - T src_i|^2 (Umeyama 1991, via Eigen::umeyama). */
Eigen::Isometry3d umeyamaSe3(const std::vector<Eigen::Vector3d>& src,
                             const std::vector<Eigen::Vector3d>& dst);

struct AteResult
{
	SummaryStats trans_m;  ///< |p_gt - p_est'| per pair; .rmse is "the" ATE
	SummaryStats rot_deg;  ///< angle(R_gt^T R_est') per pair
	/** Applied to the estimate (est' = alignment * est); identity if not
	 * aligned. */
	Eigen::Isometry3d alignment = Eigen::Isometry3d::Identity();
	EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

/** Absolute trajectory error, with (align_se3) or without alignment. */
AteResult absoluteTrajectoryError(const PosePairs& pairs, bool align_se3);

struct RpeOptions
{
	std::vector<double> lengths_m = {10, 20, 30, 40, 50, 60, 70, 80, 90, 100};
};

struct RpeLengthResult
{
	double length_m = 0;
	size_t segments = 0;
	double trans_err_pct = kNaN;
	double rot_err_deg_per_m = kNaN;
};

struct RpeResult
{
	size_t segments = 0;
	double trans_err_pct = kNaN;  ///< mean over all segments of all lengths
	double rot_err_deg_per_m = kNaN;
	std::vector<RpeLengthResult> per_length;
};

/** KITTI odometry benchmark error: every pair i starts one segment per
 * length L, ending at the first pair j whose GT distance travelled from i
 * is >= L; E = (est_i^-1 est_j)^-1 (gt_i^-1 gt_j); errors |t(E)|/L and
 * angle(R(E))/L, averaged over all segments. */
RpeResult relativePoseError(const PosePairs& pairs,
                            const RpeOptions& opts = {});

struct VerticalDrift
{
	double distance_m = kNaN;     ///< GT path length over the pairs
	double end_abs_err_m = kNaN;  ///< |e_z| at the last pair
	double max_abs_err_m = kNaN;  ///< max |e_z| over the pairs
	double end_pct = kNaN;        ///< end_abs_err_m / distance_m * 100
	double max_pct = kNaN;        ///< max_abs_err_m / distance_m * 100
};

/** e_z(i) = (z_est(i) - z_est(0)) - (z_gt(i) - z_gt(0)): change of the
 * height error since the first pair, so a constant offset is not drift. */
VerticalDrift verticalDrift(const PosePairs& pairs);

/** Paper Table 5: how far the final pose is from the first one when the
 * platform physically returned to its start pose. */
struct ReturnToStartError
{
	double t_first_s = kNaN, t_last_s = kNaN;
	/** Z-Y-X Euler angles of R_first^T R_last (R = Rz(yaw) Ry(pitch)
	 * Rx(roll)).*/
	double roll_deg = kNaN, pitch_deg = kNaN, yaw_deg = kNaN;
	/** sqrt(roll^2 + pitch^2 + yaw^2): the paper's "Total Rot." (its Table 5
	 * rows satisfy this, e.g. 5.68, 3.95, 6.14 -> 9.25). */
	double total_rot_deg = kNaN;
	/** Geodesic angle of R_first^T R_last (the single rotation angle). */
	double angle_deg = kNaN;
	/** p_last - p_first in a frame at the first position with z up and x
	 * along the first heading (Rz(yaw_first)^T (p_last - p_first)), so z is
	 * the altitude error; equals the map frame for non-georeferenced maps. */
	double x_m = kNaN, y_m = kNaN, z_m = kNaN;
	double total_trans_m = kNaN;  ///< |p_last - p_first|
};

ReturnToStartError returnToStartError(const core::StampedPose& first,
                                      const core::StampedPose& last);
/** First and last poses of a trajectory (throws if empty). */
ReturnToStartError returnToStartError(const core::Trajectory& traj);

/** The estimate's closure relative to the GT's own closure over the same
 * span, for runs whose GT does not return exactly to its start: rotation
 * components from R_gt_rel^T R_est_rel (R_rel = R_first^T R_last), x/y/z the
 * difference of the two level-frame displacements. */
ReturnToStartError returnToStartErrorVsGt(const core::StampedPose& est_first,
                                          const core::StampedPose& est_last,
                                          const Eigen::Isometry3d& gt_first,
                                          const Eigen::Isometry3d& gt_last);

struct GnssDriftOptions
{
	double interval_s = 10.0;  ///< paper: 0.1 Hz
	/** A sample time uses the nearest fix within this offset; no fix within
	 * it (GNSS dropout) skips the sample. */
	double max_fix_offset_s = 0.5;
};

struct GnssDriftSample
{
	double t_s = 0;  ///< time of the GNSS fix used
	Eigen::Vector3d est = Eigen::Vector3d::Zero(),
	                gnss = Eigen::Vector3d::Zero();
	double dist_3d_m = 0, dist_2d_m = 0;
	double aligned_dist_3d_m = kNaN;
};

struct GnssDriftResult
{
	double t0_s = kNaN;
	size_t sample_times = 0;  ///< t0, t0 + interval, ... inside the overlap
	size_t skipped_no_fix = 0;
	std::vector<GnssDriftSample> samples;
	SummaryStats dist_3d_m, dist_2d_m;
	/** After the SE(3) Umeyama alignment of the estimate samples onto the
	 * GNSS samples (needs >= 3 samples), for estimates in an unrelated
	 * frame. */
	SummaryStats aligned_dist_3d_m;
	Eigen::Isometry3d alignment = Eigen::Isometry3d::Identity();
	EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

/** Paper Table 6. Sample times t_k = t0 + k * interval_s with
 * t0 = max(first estimate, first fix), while t_k <= min(last estimate,
 * last fix); at each, the fix nearest to t_k (|dt| <= max_fix_offset_s) is
 * compared with the estimate interpolated at that fix's time. Throws if the
 * two tracks do not overlap in time. */
GnssDriftResult gnssDrift(const core::Trajectory& est,
                          const PositionTrack& gnss,
                          const GnssDriftOptions& opts = {});

/** Rotation angle of R in degrees, in [0, 180]. */
double rotationAngleDeg(const Eigen::Matrix3d& R);
/** Z-Y-X Euler angles (roll, pitch, yaw) in degrees of R = Rz Ry Rx;
 * yaw and roll in (-180, 180], pitch in [-90, 90]. */
Eigen::Vector3d rollPitchYawDeg(const Eigen::Matrix3d& R);

}  // namespace forest_slam::eval
