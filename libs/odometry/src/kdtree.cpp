#include <forest_slam/odometry/kdtree.h>

#include <nanoflann.hpp>

#include <limits>

namespace forest_slam::odometry
{
namespace
{
struct CloudAdaptor
{
	const std::vector<Eigen::Vector3f>* pts;
	size_t kdtree_get_point_count() const { return pts->size(); }
	float kdtree_get_pt(size_t i, size_t dim) const { return (*pts)[i][dim]; }
	template <class BBOX>
	bool kdtree_get_bbox(BBOX&) const
	{
		return false;
	}
};
/** One nearest point below a bound, replaced only by a strictly nearer
 * one (as nanoflann's KNNResultSet with k = 1). */
struct NearestBelowResult
{
	float best;
	uint32_t index = 0;
	bool found = false;
	bool full() const { return found; }
	bool addPoint(float dist, uint32_t i)
	{
		if (dist < best) best = dist, index = i, found = true;
		return true;
	}
	float worstDist() const { return best; }
};

using Index = nanoflann::KDTreeSingleIndexAdaptor<
    nanoflann::L2_Simple_Adaptor<float, CloudAdaptor>, CloudAdaptor, 3,
    uint32_t>;
}  // namespace

struct KdTree::Impl
{
	CloudAdaptor adaptor;
	std::unique_ptr<Index> index;
};

KdTree::KdTree() : impl_(std::make_unique<Impl>()) {}
KdTree::~KdTree() = default;
KdTree::KdTree(KdTree&&) noexcept = default;
KdTree& KdTree::operator=(KdTree&&) noexcept = default;

void KdTree::build(const std::vector<Eigen::Vector3f>& pts)
{
	pts_.clear();
	pts_.reserve(pts.size());
	for (const auto& p : pts)
		if (p.allFinite()) pts_.push_back(p);
	impl_->adaptor.pts = &pts_;
	impl_->index = std::make_unique<Index>(
	    3, impl_->adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
	if (!pts_.empty()) impl_->index->buildIndex();
}

size_t KdTree::knn(const Eigen::Vector3f& q, size_t k,
                   std::vector<uint32_t>& idx, std::vector<float>& d2) const
{
	// nanoflann's knnSearch: the k-th distance starts at the largest float.
	return knnBelow(q, k, std::numeric_limits<float>::max(), idx, d2);
}

size_t KdTree::knnBelow(const Eigen::Vector3f& q, size_t k, float bound_d2,
                        std::vector<uint32_t>& idx,
                        std::vector<float>& d2) const
{
	if (pts_.empty() || k == 0)
	{
		idx.clear();
		d2.clear();
		return 0;
	}
	k = std::min(k, pts_.size());
	idx.resize(k);
	d2.resize(k);
	// nanoflann's k-NN set, its k-th distance (the pruning bound until k
	// points are in) started at the bound instead of the largest float.
	nanoflann::KNNResultSet<float, uint32_t> r(k);
	r.init(idx.data(), d2.data());
	d2[k - 1] = bound_d2;
	impl_->index->findNeighbors(r, q.data(), nanoflann::SearchParams());
	const size_t n = r.size();
	idx.resize(n);
	d2.resize(n);
	return n;
}

bool KdTree::nearestBelow(const Eigen::Vector3f& q, float bound_d2,
                          uint32_t& idx, float& d2) const
{
	if (pts_.empty()) return false;
	NearestBelowResult r{bound_d2};
	impl_->index->findNeighbors(r, q.data(), nanoflann::SearchParams());
	if (!r.found) return false;
	idx = r.index;
	d2 = r.best;
	return true;
}

}  // namespace forest_slam::odometry
