#pragma once
// A place descriptor for loop candidates that the current estimate cannot
// find (drift of metres): a Scan Context-style polar grid of a keyframe's
// local map. The cloud is levelled first (roll and pitch from the pose
// estimate, which gravity keeps right), so only the yaw between two visits
// of a place is unknown: it is a circular shift of the sectors.
//  - cell value: height span (highest - lowest point) of the cell, so the
//    ground alone gives a low value and stems, shrubs and crowns a high one,
//    whatever the slope and the sensor height;
//  - ring key: mean cell value per ring (yaw-invariant), for retrieval;
//  - distance: 1 - mean cosine similarity of the columns (sectors) that
//    both descriptors see, at the best circular shift; the shift gives the
//    yaw, refined to a fraction of a sector by a parabola.
#include <Eigen/Core>
#include <Eigen/Geometry>

#include <vector>

namespace forest_slam::loop
{
struct PlaceDescriptorOptions
{
	int rings = 20;
	int sectors = 60;
	double radius_m = 20.0;
};

class PlaceDescriptor
{
   public:
	PlaceDescriptor() = default;
	/** From points in a levelled frame centred on the keyframe (z up). */
	PlaceDescriptor(const std::vector<Eigen::Vector3f>& levelled,
	                const PlaceDescriptorOptions& o);
	bool empty() const { return cells_.size() == 0; }
	int rings() const { return static_cast<int>(cells_.rows()); }
	int sectors() const { return static_cast<int>(cells_.cols()); }
	const Eigen::MatrixXf& cells() const { return cells_; }
	const Eigen::VectorXf& ringKey() const { return ring_key_; }
	/** Fraction of the cells that hold points. */
	double occupancy() const { return occupancy_; }

   private:
	Eigen::MatrixXf cells_;  ///< rings x sectors, 0 = no point
	Eigen::VectorXf ring_key_;
	double occupancy_ = 0;
};

struct DescriptorMatch
{
	double distance = 1;  ///< 0 = identical, 1 = unrelated
	/** q_a = Rz(yaw) q_b between the levelled frames (a: the first
	 * argument of matchDescriptors). */
	double yaw_rad = 0;
};

/** Best circular shift of b against a (both from the same options). */
DescriptorMatch matchDescriptors(const PlaceDescriptor& a,
                                 const PlaceDescriptor& b);

/** The rotation that levels a pose's frame: L * R has no roll and pitch,
 * the yaw of R (about the world vertical) kept out. */
Eigen::Matrix3d levellingRotation(const Eigen::Matrix3d& R);

/** Yaw of R about the world vertical (x axis projected). */
double yawOf(const Eigen::Matrix3d& R);

}  // namespace forest_slam::loop
