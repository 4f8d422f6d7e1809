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
	/** knn(q, k) restricted to the points below `bound_d2`: the same
	 * neighbours and distances when the k-th of them is below the bound
	 * (fewer otherwise), found without visiting the branches beyond it. */
	size_t knnBelow(const Eigen::Vector3f& q, size_t k, float bound_d2,
	                std::vector<uint32_t>& idx, std::vector<float>& d2) const;
	/** The nearest point if its squared distance is below `bound_d2`: its
	 * index and squared distance, as knn(q, 1) gives them (the same point
	 * among equally near ones). The bound only prunes the search: the
	 * branches it skips hold no point nearer than it, which is what makes
	 * an ICP's queries cheaper (its gate, or the distance to last
	 * iteration's match, which is at least the nearest's). */
	bool nearestBelow(const Eigen::Vector3f& q, float bound_d2, uint32_t& idx,
	                  float& d2) const;

   private:
	struct Impl;
	std::vector<Eigen::Vector3f> pts_;
	std::unique_ptr<Impl> impl_;
};

}  // namespace forest_slam::odometry
