#include <forest_slam/cluster/hierarchical_kmeans.h>
#include <forest_slam/trees/stem_clustering.h>

#include <nanoflann.hpp>

#include <algorithm>
#include <numeric>

namespace forest_slam::trees
{
namespace
{
struct Adaptor
{
	const Points2D& p;
	size_t kdtree_get_point_count() const { return p.size(); }
	double kdtree_get_pt(size_t i, size_t d) const { return p[i][int(d)]; }
	template <class B>
	bool kdtree_get_bbox(B&) const
	{
		return false;
	}
};
using Tree = nanoflann::KDTreeSingleIndexAdaptor<
    nanoflann::L2_Simple_Adaptor<double, Adaptor>, Adaptor, 2, size_t>;

int findRoot(std::vector<int>& parent, int i)
{
	while (parent[i] != i) i = parent[i] = parent[parent[i]];
	return i;
}
}  // namespace

std::vector<int> sliceKMeansLeaves(const Points2D& p, int branching,
                                   int leaf_points)
{
	std::vector<int> leaf(p.size(), 0);
	if (p.empty()) return leaf;
	Eigen::Vector2d mean = Eigen::Vector2d::Zero();
	for (const auto& q : p) mean += q;
	mean /= double(p.size());
	std::vector<Eigen::Vector3f> pts;
	pts.reserve(p.size());
	for (const auto& q : p)
		pts.emplace_back(float(q.x() - mean.x()), float(q.y() - mean.y()), 0.f);
	cluster::ClusterOptions co;
	co.branching_factor = std::max(2, branching);
	co.max_cluster_points = std::max(2, leaf_points);
	co.min_cluster_points = 1;  // no small-cluster merge: the neighbourhood
	                            // criterion below joins leaves instead
	co.kmeans_iterations = 20;
	const auto labels = cluster::hierarchicalKMeans(pts, co);
	for (size_t i = 0; i < p.size(); i++) leaf[i] = std::max(0, labels.cluster[i]);
	return leaf;
}

std::vector<std::vector<size_t>> mergeLeavesByNeighbourhood(
    const Points2D& p, const std::vector<int>& leaf, double link_m)
{
	std::vector<std::vector<size_t>> out;
	if (p.empty()) return out;
	const int n_leaves = *std::max_element(leaf.begin(), leaf.end()) + 1;
	std::vector<int> parent(n_leaves);
	std::iota(parent.begin(), parent.end(), 0);
	Adaptor ad{p};
	Tree tree(2, ad, nanoflann::KDTreeSingleIndexAdaptorParams(10));
	tree.buildIndex();
	std::vector<std::pair<size_t, double>> hits;
	nanoflann::SearchParams sp;
	sp.sorted = false;
	for (size_t i = 0; i < p.size(); i++)
	{
		const double q[2] = {p[i].x(), p[i].y()};
		tree.radiusSearch(q, link_m * link_m, hits, sp);
		for (const auto& h : hits)
		{
			const int a = findRoot(parent, leaf[i]),
			          b = findRoot(parent, leaf[h.first]);
			if (a != b) parent[a] = b;
		}
	}
	std::vector<int> slot(n_leaves, -1);
	for (size_t i = 0; i < p.size(); i++)
	{
		const int r = findRoot(parent, leaf[i]);
		if (slot[r] < 0) slot[r] = int(out.size()), out.emplace_back();
		out[slot[r]].push_back(i);
	}
	std::sort(out.begin(), out.end(),
	          [](const auto& a, const auto& b) { return a.size() > b.size(); });
	return out;
}

}  // namespace forest_slam::trees
