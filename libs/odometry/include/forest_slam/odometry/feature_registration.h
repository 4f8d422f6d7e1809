#pragma once
// Transform estimation between feature sets (paper §4.4–4.5): point-to-line
// residuals for edge points and point-to-plane residuals for planar points,
// solved with Levenberg–Marquardt (Ceres) under a robust (Huber) loss, with
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
	int outer_iterations = 12;	///< correspondence searches
	int lm_iterations = 8;	///< Ceres LM iterations per outer iteration
	/** Correspondence gate: shrinks geometrically from max to min over the
	 * first half of the outer iterations (coarse to fine: far matches pull
	 * a poor guess in, near matches make the final estimate precise). */
	double max_correspondence_m = 1.0;
	double min_correspondence_m = 0.3;
	int knn = 8;  ///< neighbours to fit a plane
	/** Neighbours to fit a line: few, so the two silhouettes of one stem
	 * (a stem diameter apart) are not blended into one line. */
	int edge_knn = 4;
	/** The k neighbours must lie within this of the query (the nearest one
	 * within the correspondence gate): voxelized maps are sparse. */
	double max_neighbourhood_m = 1.0;
	double huber_m = 0.1;  ///< robust loss scale
	/** Plane fit accepted if its smallest eigenvalue is below this fraction
	 * of the largest; line fit if the largest dominates the middle one by
	 * line_ratio. */
	double plane_flatness = 0.1;
	double line_ratio = 3.0;
	/** Motion-model prior (when the caller gives one): in directions the
	 * geometry leaves unconstrained (a corridor, an open field) the pose
	 * stays at the prediction instead of drifting; where the scan constrains
	 * the pose, hundreds of residuals outweigh it. 0 disables. */
	double prior_translation_sigma_m = 0.1;
	double prior_rotation_sigma_deg = 1.0;
	/** Converged when the update is below these. */
	double converged_translation_m = 1e-4;
	double converged_rotation_rad = 1e-5;

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
							const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
						  const std::string& section) const override;
};

/** Target feature clouds with their search indices. */
struct FeatureTarget
{
	KdTree edges, planar;
	void build(const std::vector<Eigen::Vector3f>& edge_pts,
			   const std::vector<Eigen::Vector3f>& planar_pts)
	{
		edges.build(edge_pts);
		planar.build(planar_pts);
	}
};

struct RegistrationResult
{
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  ///< source -> target
	int iterations = 0;
	bool converged = false;
	size_t edge_matches = 0, planar_matches = 0;
	double rmse_m = 0;	///< of the final residuals
	/** Eigenvalues of the 6x6 normal matrix (ascending): small ones mark
	 * directions the geometry does not constrain (degeneracy). */
	Eigen::Matrix<double, 6, 1> information_eigenvalues =
		Eigen::Matrix<double, 6, 1>::Zero();
};

/** Estimates T such that T * source ≈ target, starting from `initial`;
 * with `prior`, adds the motion-model prior factor centred on it. */
RegistrationResult registerFeatures(
	const FeatureTarget& target, const std::vector<Eigen::Vector3f>& src_edges,
	const std::vector<Eigen::Vector3f>& src_planar,
	const Eigen::Isometry3d& initial, const RegistrationOptions& opts,
	const Eigen::Isometry3d* prior = nullptr);

}  // namespace forest_slam::odometry
