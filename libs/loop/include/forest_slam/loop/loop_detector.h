#pragma once
// Loop candidates and their verification.
//  - candidates: keyframes at least min_travel_m back along the path whose
//    current estimate lies within a radius of the current keyframe; the
//    radius grows with the distance travelled since (odometry drift);
//  - verification: point-to-plane ICP of the current submap (the keyframe
//    and its predecessors) onto the candidate's submap (its neighbours on
//    both sides), then gates: overlap, inlier RMSE, information (no
//    corridor-like degeneracy), consistency of the correction with the
//    drift the odometry can have accumulated (Mahalanobis, chi-square 6
//    dof), and uniqueness: ICP started from guesses displaced by a few
//    metres must not find another alignment as good (regular plantations,
//    trails that look the same along their length).
//  - descriptor candidates: the keyframes at least min_travel_m back whose
//    place descriptor (place_descriptor.h) matches best, wherever the
//    current estimate puts them; ICP is seeded with the descriptor's yaw,
//    the drift prior gates only what gravity keeps observable (height,
//    tilt), the descriptor must agree with ICP, and the uniqueness test
//    also restarts ICP from the seed turned by 90, 180 and 270 degrees.
#include <forest_slam/loop/icp.h>
#include <forest_slam/loop/loop_options.h>
#include <forest_slam/loop/place_descriptor.h>

#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

namespace forest_slam::loop
{
struct Keyframe
{
	size_t id = 0;
	double stamp_s = 0;
	double travelled_m = 0;  ///< path length from the start
	/** Odometry pose relative to the previous keyframe (identity first). */
	Eigen::Isometry3d odom_edge = Eigen::Isometry3d::Identity();
	std::vector<Eigen::Vector3f> cloud;  ///< keyframe sensor frame
	/** Gravity's "up" in the keyframe frame from the IMU attitude filter
	 * (none without IMU): levels the map at the end (levelling.h). */
	std::optional<Eigen::Vector3d> up;
	EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

struct Closure
{
	size_t from = 0;  ///< the older (candidate) keyframe
	size_t to = 0;    ///< the current keyframe
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  ///< from^-1 to
	double overlap = 0, rmse_m = 0, chi2 = 0, travelled_m = 0;
	/** How far the measured T is from the estimate's from^-1 to when it was
	 * verified: translation and rotation of their difference (what an
	 * optimisation would correct; 0 before ICP ran). */
	double error_m = 0, error_deg = 0;
	bool accepted = false;
	std::string reason;       ///< why rejected ("" when accepted)
	bool descriptor = false;  ///< a descriptor candidate (else geometric)
	double descriptor_distance = 1;
	EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

using Poses =
    std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>>;

/** Candidate keyframes for `current`, nearest first (estimates in `poses`,
 * one per keyframe). */
std::vector<size_t> loopCandidates(const std::vector<Keyframe>& kfs,
                                   const Poses& poses, size_t current,
                                   const LoopOptions& o);

struct DescriptorCandidate
{
	size_t from = 0;
	DescriptorMatch match;
};

/** The place descriptor of keyframe `id` (its cloud and
 * o.descriptor_keyframes predecessors, levelled with the estimate's roll
 * and pitch). */
PlaceDescriptor keyframeDescriptor(const std::vector<Keyframe>& kfs,
                                   const Poses& poses, size_t id,
                                   const LoopOptions& o);

/** Descriptor matches of `current` among the keyframes at least
 * o.min_travel_m back, best first: ring-key retrieval, then the full
 * comparison, at most o.descriptor_candidates within
 * o.descriptor_max_distance, from different places of the path. A match
 * that only repeats a geometric candidate (in `geometric`: near it along
 * the path, and the estimate agrees with the match's yaw and puts the two
 * keyframes within 2 icp_start_distance_m) is left out: ICP from the
 * estimate tries that hypothesis already. */
std::vector<DescriptorCandidate> descriptorCandidates(
    const std::vector<Keyframe>& kfs, const Poses& poses,
    const std::vector<PlaceDescriptor>& descriptors, size_t current,
    const std::vector<size_t>& geometric, const LoopOptions& o);

/** Points of keyframes [first, last] in the frame of keyframe `ref`. */
std::vector<Eigen::Vector3f> submapCloud(const std::vector<Keyframe>& kfs,
                                         const Poses& poses, size_t first,
                                         size_t last, size_t ref,
                                         double voxel_m);

/** At most `max_points` of `pts`, evenly along the vector (0 = all). */
std::vector<Eigen::Vector3f> thinEvenly(const std::vector<Eigen::Vector3f>& pts,
                                        size_t max_points);

/** Verifies a closure between keyframes `from` (older) and `to`; ICP
 * starts from the current estimate, or from the descriptor's match when
 * `seed` is given (the gates of a descriptor candidate: see above). */
Closure verifyClosure(const std::vector<Keyframe>& kfs, const Poses& poses,
                      size_t from, size_t to, const LoopOptions& o,
                      const DescriptorMatch* seed = nullptr);

}  // namespace forest_slam::loop
