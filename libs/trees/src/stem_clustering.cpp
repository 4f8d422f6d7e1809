#include <forest_slam/cluster/hierarchical_kmeans.h>
#include <forest_slam/trees/stem_clustering.h>

#include <nanoflann.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <tuple>

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

Points2D thinToCells(const Points2D& p, double cell_m)
{
	std::vector<std::pair<std::pair<int64_t, int64_t>, size_t>> keyed;
	keyed.reserve(p.size());
	for (size_t i = 0; i < p.size(); i++)
		keyed.push_back({{int64_t(std::floor(p[i].x() / cell_m)),
		                  int64_t(std::floor(p[i].y() / cell_m))},
		                 i});
	std::sort(keyed.begin(), keyed.end());
	Points2D out;
	for (size_t j = 0; j < keyed.size();)
	{
		Eigen::Vector2d sum = Eigen::Vector2d::Zero();
		size_t k = j;
		for (; k < keyed.size() && keyed[k].first == keyed[j].first; k++)
			sum += p[keyed[k].second];
		out.push_back(sum / double(k - j));
		j = k;
	}
	return out;
}

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
	co.kmeans_iterations = 10;
	const auto labels = cluster::hierarchicalKMeans(pts, co);
	for (size_t i = 0; i < p.size(); i++)
		leaf[i] = std::max(0, labels.cluster[i]);
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
	// Points closer than link_m / 8 in the same leaf link the same leaves:
	// search from one representative of each such group only (slices of a
	// voxelised map stack ~10 points on every spot of a stem).
	const double cell = link_m / 8;
	std::vector<std::tuple<int64_t, int64_t, int, size_t>> keyed;
	keyed.reserve(p.size());
	for (size_t i = 0; i < p.size(); i++)
		keyed.emplace_back(int64_t(std::floor(p[i].x() / cell)),
		                   int64_t(std::floor(p[i].y() / cell)), leaf[i], i);
	std::sort(keyed.begin(), keyed.end());
	Points2D rep;
	std::vector<int> rep_leaf;
	for (size_t j = 0; j < keyed.size(); j++)
	{
		const auto& [x, y, l, i] = keyed[j];
		if (j > 0 && std::get<0>(keyed[j - 1]) == x &&
		    std::get<1>(keyed[j - 1]) == y && std::get<2>(keyed[j - 1]) == l)
			continue;
		rep.push_back(p[i]);
		rep_leaf.push_back(l);
	}
	Adaptor ad{rep};
	Tree tree(2, ad, nanoflann::KDTreeSingleIndexAdaptorParams(10));
	tree.buildIndex();
	std::vector<std::pair<size_t, double>> hits;
	nanoflann::SearchParams sp;
	sp.sorted = false;
	for (size_t i = 0; i < rep.size(); i++)
	{
		const double q[2] = {rep[i].x(), rep[i].y()};
		tree.radiusSearch(q, link_m * link_m, hits, sp);
		for (const auto& h : hits)
		{
			const int a = findRoot(parent, rep_leaf[i]),
			          b = findRoot(parent, rep_leaf[h.first]);
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
