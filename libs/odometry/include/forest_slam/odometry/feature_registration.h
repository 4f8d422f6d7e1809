#pragma once
// Transform estimation between feature sets (paper §4.4–4.5): point-to-line
// residuals for edge points and point-to-plane residuals for planar points,
// solved with Levenberg–Marquardt under a robust (Huber) loss, with
// correspondences re-found by k-NN each outer iteration. The same code does
// scan-to-scan (target = previous scan) and scan-to-map (target = local map).
#include <forest_slam/odometry/kdtree.h>
#include <mrpt/config/CLoadableOptions.h>

#include <Eigen/Geometry>
#include <vector>

namespace forest_slam::odometry
{
struct RegistrationOptions : public mrpt::config::CLoadableOptions
{
	int outer_iterations = 4;  ///< correspondence searches
	/** Threads of the correspondence search (the k-NN queries, ~half of a
	 * scan's time); results do not depend on it. */
	int threads = 2;
	int lm_iterations = 4;  ///< LM iterations per correspondence search
	/** Correspondence gate: shrinks geometrically from max to min over the
	 * first half of the outer iterations (coarse to fine: far matches pull
	 * a poor guess in, near matches make the final estimate precise). */
	double max_correspondence_m = 1.0;
	double min_correspondence_m = 0.3;
	int knn = 5;  ///< neighbours to fit a plane
	/** Neighbours to fit a line: few, so the two silhouettes of one stem
	 * (a stem diameter apart) are not blended into one line. */
	int edge_knn = 4;
	/** The k neighbours must lie within this of the query (the nearest one
	 * within the correspondence gate): voxelized maps are sparse. */
	double max_neighbourhood_m = 0.5;
	double huber_m = 0.1;  ///< robust loss scale
	/** Plane fit accepted if its smallest eigenvalue is below this fraction
	 * of the largest; line fit if the largest dominates the middle one by
	 * line_ratio. */
	double plane_flatness = 0.1;
	double line_ratio = 3.0;
	/** A plane's neighbours must spread in two directions: middle
	 * eigenvalue >= this fraction of the largest (0: any). Set by the
	 * odometry near the start (OdometryOptions::start_plane_spread_ratio),
	 * not an INI key of its own. */
	double min_plane_spread_ratio = 0;
	/** Motion-model prior (when the caller gives one): in directions the
	 * geometry leaves unconstrained (a corridor, an open field) the pose
	 * stays at the prediction instead of drifting; where the scan constrains
	 * the pose, hundreds of residuals outweigh it. 0 disables. */
	double prior_translation_sigma_m = 0.1;
	double prior_rotation_sigma_deg = 1.0;
	/** IMU gravity prior on roll and pitch (when the caller gives "up"):
	 * the accelerometer sees gravity, so roll/pitch cannot drift [deg]. 0
	 * disables. */
	double gravity_sigma_deg = 3.0;
	/** A correspondence search keeps a feature's match (plane or line, or
	 * no match) when the feature moved less than this since it was
	 * searched and the match still passes the search's gate (MatchReach):
	 * once the pose changes by millimetres, re-searching every
	 * neighbourhood costs k-NN time for the same matches. Also across a
	 * shrinking gate: a match found at 1 m whose neighbour and residual lie
	 * within 0.3 m is the match a 0.3 m search would find. 0 re-searches
	 * all. */
	double rematch_distance_m = 0;
	/** Converged when the update is below these. */
	double converged_translation_m = 1e-4;
	double converged_rotation_rad = 1e-5;

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& section) const override;
};

/** One scalar residual: the signed distance n.x + d of the transformed
 * source point x to a plane (unit n). A point-to-line match is two rows,
 * the two orthogonal planes that contain the line. */
struct PlaneRow
{
	Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
	double d = 0;
};

/** What a correspondence search tells besides its rows: the smallest gate
 * the match passes (its nearest neighbour's distance, or its residual where
 * the gate bounds that). A search at a smaller gate gives the same match
 * while this stays within it, so registerFeatures keeps the match of a
 * feature that barely moved when the gate shrinks. */
struct MatchReach
{
	double gate_needed = 0;
};

/** What a registration matches against: scan-to-scan (FeatureTarget, k-d
 * trees over the previous scan's features) or scan-to-map (LocalMap). */
class RegistrationTarget
{
   public:
	virtual ~RegistrationTarget() = default;
	/** The plane of the planar neighbourhood of x, if one lies within `gate`.
	 * A smaller gate never turns a failed search into a match; `reach`
	 * says how small a gate this match passes. */
	virtual bool matchPlane(const Eigen::Vector3f& x, double gate,
	                        const RegistrationOptions& o, PlaneRow& out,
	                        MatchReach& reach) const = 0;
	/** The line of the edge neighbourhood of x, if one lies within `gate`. */
	virtual bool matchLine(const Eigen::Vector3f& x, double gate,
	                       const RegistrationOptions& o, PlaneRow& a,
	                       PlaneRow& b, MatchReach& reach) const = 0;
};

/** Target feature clouds with their k-d tree indices (nanoflann). */
struct FeatureTarget : public RegistrationTarget
{
	KdTree edges, planar;
	void build(const std::vector<Eigen::Vector3f>& edge_pts,
	           const std::vector<Eigen::Vector3f>& planar_pts)
	{
		edges.build(edge_pts);
		planar.build(planar_pts);
	}
	bool matchPlane(const Eigen::Vector3f& x, double gate,
	                const RegistrationOptions& o, PlaneRow& out,
	                MatchReach& reach) const override;
	bool matchLine(const Eigen::Vector3f& x, double gate,
	               const RegistrationOptions& o, PlaneRow& a, PlaneRow& b,
	               MatchReach& reach) const override;
};

/** Line as two orthogonal planes through `a` (unit direction `dir`). */
void lineToPlanes(const Eigen::Vector3d& a, const Eigen::Vector3d& dir,
                  PlaneRow& p, PlaneRow& q);

struct RegistrationResult
{
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  ///< source -> target
	int iterations = 0;
	bool converged = false;
	size_t edge_matches = 0, planar_matches = 0;
	double rmse_m = 0;  ///< of the final residuals
	/** Eigenvalues of the 6x6 normal matrix (ascending): small ones mark
	 * directions the geometry does not constrain (degeneracy). */
	Eigen::Matrix<double, 6, 1> information_eigenvalues =
	    Eigen::Matrix<double, 6, 1>::Zero();
	/** The 6x6 normal matrix itself, in the update's parameterisation
	 * [rotation (left, rad), translation (m)]: its weak eigenvectors are the
	 * degenerate directions (degeneracy.h). */
	Eigen::Matrix<double, 6, 6> information =
	    Eigen::Matrix<double, 6, 6>::Zero();
	/** RMS distance of the matched points from the sensor [m]: a rotation
	 * of 1 rad moves them this far on average, the scale that makes the
	 * rotation and translation parts of `information` comparable
	 * (degeneracy.h). */
	double lever_arm_m = 0;
	/** With RegistrationPriors::edge_fraction/planar_fraction: the
	 * correction (rotation vector [rad], translation [m]) of the sweep's
	 * motion over the whole sweep, in the frame of the first firing; a
	 * point fired at fraction s of the sweep, deskewed to q, is at
	 * exp(s w) q + s v. Zero otherwise. */
	Eigen::Matrix<double, 6, 1> sweep_twist =
	    Eigen::Matrix<double, 6, 1>::Zero();
};

/** Sweep-twist prior of registerFeatures (a correction of the deskew's
 * motion over one sweep): sigmas of its rotation and translation. A
 * handheld gait swings the lidar by 2-5 deg from one 0.1 s sweep to the
 * next (forest-sim handheld). */
constexpr double kSweepTwistSigmaRad = 5.0 * M_PI / 180;
constexpr double kSweepTwistSigmaM = 0.1;

/** Optional priors of a registration. */
struct RegistrationPriors
{
	/** Motion-model prediction: holds the pose where the geometry is weak. */
	const Eigen::Isometry3d* motion = nullptr;
	/** "Up" (against gravity) in the source frame, from the IMU attitude:
	 * keeps roll and pitch on gravity (sigma: gravity_sigma_deg). */
	const Eigen::Vector3d* up_in_source = nullptr;
	/** Firing time of every source feature as a fraction of the sweep
	 * (0..1, same order as src_edges and src_planar). When both are set the
	 * registration also estimates a correction of the motion the source
	 * was deskewed with (RegistrationResult::sweep_twist): for sweeps no
	 * gyro measured (an IMU gap), where a handheld rig's swing makes the
	 * constant-velocity deskew several degrees wrong. */
	const std::vector<float>* edge_fraction = nullptr;
	const std::vector<float>* planar_fraction = nullptr;
};

/** Estimates T such that T * source ≈ target, starting from `initial`:
 * Levenberg–Marquardt on SE(3) with analytic Jacobians and a Huber loss
 * (iteratively reweighted), correspondences re-found each outer iteration
 * with a shrinking gate. */
RegistrationResult registerFeatures(
    const RegistrationTarget& target,
    const std::vector<Eigen::Vector3f>& src_edges,
    const std::vector<Eigen::Vector3f>& src_planar,
    const Eigen::Isometry3d& initial, const RegistrationOptions& opts,
    const RegistrationPriors& priors = {});

/** Convenience: motion prior only (scan-to-scan and older callers). */
inline RegistrationResult registerFeatures(
    const RegistrationTarget& target,
    const std::vector<Eigen::Vector3f>& src_edges,
    const std::vector<Eigen::Vector3f>& src_planar,
    const Eigen::Isometry3d& initial, const RegistrationOptions& opts,
    const Eigen::Isometry3d* prior)
{
	RegistrationPriors p;
	p.motion = prior;
	return registerFeatures(target, src_edges, src_planar, initial, opts, p);
}

}  // namespace forest_slam::odometry
