#pragma once
// k-nearest-neighbour search over a float point cloud (nanoflann).
#include <Eigen/Core>

#include <memory>
#include <vector>

namespace forest_slam::odometry
{
class KdTree
{
   public:
	KdTree();
	~KdTree();
	KdTree(KdTree&&) noexcept;
	KdTree& operator=(KdTree&&) noexcept;
	/** Builds the index over a copy of `pts` (non-finite points dropped). */
	void build(const std::vector<Eigen::Vector3f>& pts);
	const std::vector<Eigen::Vector3f>& points() const { return pts_; }
	bool empty() const { return pts_.empty(); }
	/** Up to k nearest points: indices into points() and squared distances,
	 * nearest first. */
	size_t knn(const Eigen::Vector3f& q, size_t k, std::vector<uint32_t>& idx,
	           std::vector<float>& d2) const;

   private:
	struct Impl;
	std::vector<Eigen::Vector3f> pts_;
	std::unique_ptr<Impl> impl_;
};

}  // namespace forest_slam::odometry
