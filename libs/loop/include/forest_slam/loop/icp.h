#pragma once
// Point-to-plane ICP with a Cauchy kernel (loop verification): source
// points onto a target with normals, Gauss-Newton on SE(3), the
// correspondence gate shrinking from a start to a final distance.
#include <forest_slam/loop/keyframe_cloud.h>

#include <Eigen/Geometry>
#include <memory>

namespace forest_slam::odometry
{
class KdTree;
}

namespace forest_slam::loop
{
struct IcpOptions
{
	int iterations = 50;
	double start_distance_m = 1.5;
	double final_distance_m = 0.4;
	double kernel_m = 0.1;  ///< Cauchy scale of the point-to-plane residual
};

struct IcpResult
{
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  ///< source->target
	double overlap = 0;  ///< fraction of source points matched (final gate)
	double rmse_m = 0;   ///< point-to-plane RMSE of the matched points
	size_t matches = 0;
	/** Eigenvalues of J^T J of the final matches (ascending, 6 dof):
	 * weakest/strongest tells a degenerate alignment (a corridor). */
	Eigen::Matrix<double, 6, 1> information_eigenvalues =
	    Eigen::Matrix<double, 6, 1>::Zero();
	bool converged = false;
	int iterations = 0;  ///< Gauss-Newton steps taken (align())
};

/** A target cloud with its search index, reused for several ICP runs. */
class IcpTarget
{
   public:
	explicit IcpTarget(NormalCloud cloud);
	~IcpTarget();
	const NormalCloud& cloud() const { return cloud_; }
	size_t size() const { return cloud_.points.size(); }
	IcpResult align(const std::vector<Eigen::Vector3f>& source,
	                const Eigen::Isometry3d& guess, const IcpOptions& o) const;
	/** The statistics of `align` (overlap, RMSE, information) of `source`
	 * placed at T, without iterating. */
	IcpResult evaluate(const std::vector<Eigen::Vector3f>& source,
	                   const Eigen::Isometry3d& T, const IcpOptions& o) const;

   private:
	NormalCloud cloud_;
	std::unique_ptr<odometry::KdTree> tree_;
};

}  // namespace forest_slam::loop
