#pragma once
// SE(3) pose graph over keyframes (Ceres): relative-pose factors from the
// odometry and from loop closures, and GNSS position factors tying the map
// frame to a local ENU frame through a 4-dof transform (yaw + translation:
// the map frame is already levelled with gravity). The first keyframe is
// held fixed, so the map frame keeps the project convention.
#include <Eigen/Geometry>

#include <vector>

namespace forest_slam::loop
{
using Matrix6d = Eigen::Matrix<double, 6, 6>;

struct RelativeFactor
{
	size_t a = 0, b = 0;
	Eigen::Isometry3d T_ab = Eigen::Isometry3d::Identity();  ///< a^-1 b
	/** Square root of the information (translation first, rotation as
	 * 2 * quaternion vector part). */
	Matrix6d sqrt_information = Matrix6d::Identity();
	bool robust = false;  ///< Cauchy loss (loop closures)
};

struct GnssFactor
{
	size_t node = 0;
	/** Antenna position in the node's frame (odometry offset of the fix
	 * time from the keyframe, and the lever arm). */
	Eigen::Vector3d antenna_in_node = Eigen::Vector3d::Zero();
	Eigen::Vector3d enu = Eigen::Vector3d::Zero();    ///< measured position
	Eigen::Vector3d sigma = Eigen::Vector3d::Ones();  ///< per axis [m]
	bool outlier = false;  ///< set by optimize()'s gate
};

/** p_enu = Rz(yaw) p_map + t */
struct MapToEnu
{
	double yaw = 0;
	Eigen::Vector3d t = Eigen::Vector3d::Zero();
	Eigen::Vector3d apply(const Eigen::Vector3d& p) const
	{
		return Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * p + t;
	}
};

class PoseGraph
{
   public:
	size_t addNode(const Eigen::Isometry3d& initial);
	void addFactor(const RelativeFactor& f) { factors_.push_back(f); }
	void addGnss(const GnssFactor& f) { gnss_.push_back(f); }
	size_t size() const { return poses_.size(); }
	const Eigen::Isometry3d& pose(size_t i) const { return poses_[i]; }
	void setPose(size_t i, const Eigen::Isometry3d& T) { poses_[i] = T; }
	const std::vector<GnssFactor>& gnss() const { return gnss_; }
	bool hasEnu() const { return have_enu_; }
	const MapToEnu& mapToEnu() const { return enu_; }

	/** Optimises all nodes. GNSS factors join once their fixes span
	 * `gnss_min_baseline_m` horizontally (the heading of the map frame in
	 * ENU is observable); after a solve, fixes whose residual exceeds
	 * `gnss_gate_sigma` sigmas are marked outliers and the graph is solved
	 * again without them. Returns false if Ceres failed (poses kept). */
	bool optimize(double gnss_min_baseline_m, double gnss_gate_sigma);

   private:
	std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>>
	    poses_;
	std::vector<RelativeFactor> factors_;
	std::vector<GnssFactor> gnss_;
	bool have_enu_ = false;
	MapToEnu enu_;
	bool initEnu(double min_baseline_m);
	bool solve(bool with_gnss);
};

/** sqrt information of a diagonal covariance: sigmas of x, y, z [m] and
 * of the rotation about x, y, z [rad]. */
Matrix6d sqrtInformation(double sigma_t_m, double sigma_r_rad);

}  // namespace forest_slam::loop
