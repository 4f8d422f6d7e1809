#include <forest_slam/trees/stem_clustering.h>

#include <nanoflann.hpp>

#include <algorithm>
#include <numeric>
#include <random>

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

void splitRecursive(const Points2D& p, std::vector<size_t>& idx, int k,
                    int leaf_points, std::mt19937& rng, std::vector<int>& leaf,
                    int& next_leaf)
{
	auto makeLeaf = [&]
	{
		for (size_t i : idx) leaf[i] = next_leaf;
		next_leaf++;
	};
	if (idx.size() <= size_t(leaf_points)) return makeLeaf();
	// k-means++ seeding, then Lloyd iterations.
	std::vector<Eigen::Vector2d> c;
	c.push_back(
	    p[idx[std::uniform_int_distribution<size_t>(0, idx.size() - 1)(rng)]]);
	std::vector<double> d2(idx.size());
	while (int(c.size()) < k)
	{
		double sum = 0;
		for (size_t j = 0; j < idx.size(); j++)
		{
			double m = std::numeric_limits<double>::max();
			for (const auto& cc : c)
				m = std::min(m, (p[idx[j]] - cc).squaredNorm());
			d2[j] = m, sum += m;
		}
		if (sum <= 0) break;
		double u = std::uniform_real_distribution<double>(0, sum)(rng);
		size_t j = 0;
		while (j + 1 < idx.size() && (u -= d2[j]) > 0) j++;
		c.push_back(p[idx[j]]);
	}
	if (c.size() < 2) return makeLeaf();  // all points coincide
	std::vector<int> a(idx.size(), 0);
	for (int it = 0; it < 20; it++)
	{
		bool changed = false;
		for (size_t j = 0; j < idx.size(); j++)
		{
			int bi = 0;
			double bd = std::numeric_limits<double>::max();
			for (size_t q = 0; q < c.size(); q++)
			{
				const double d = (p[idx[j]] - c[q]).squaredNorm();
				if (d < bd) bd = d, bi = int(q);
			}
			if (a[j] != bi) a[j] = bi, changed = true;
		}
		std::vector<Eigen::Vector2d> s(c.size(), Eigen::Vector2d::Zero());
		std::vector<size_t> n(c.size(), 0);
		for (size_t j = 0; j < idx.size(); j++) s[a[j]] += p[idx[j]], n[a[j]]++;
		for (size_t q = 0; q < c.size(); q++)
			if (n[q]) c[q] = s[q] / double(n[q]);
		if (!changed && it > 0) break;
	}
	std::vector<std::vector<size_t>> parts(c.size());
	for (size_t j = 0; j < idx.size(); j++) parts[a[j]].push_back(idx[j]);
	int non_empty = 0;
	for (const auto& part : parts) non_empty += !part.empty();
	if (non_empty < 2) return makeLeaf();
	idx.clear();
	idx.shrink_to_fit();
	for (auto& part : parts)
		if (!part.empty())
			splitRecursive(p, part, k, leaf_points, rng, leaf, next_leaf);
}

int findRoot(std::vector<int>& parent, int i)
{
	while (parent[i] != i) i = parent[i] = parent[parent[i]];
	return i;
}
}  // namespace

std::vector<int> hierarchicalKMeans(const Points2D& p, int branching,
                                    int leaf_points, uint32_t seed)
{
	std::vector<int> leaf(p.size(), 0);
	if (p.empty()) return leaf;
	std::vector<size_t> idx(p.size());
	std::iota(idx.begin(), idx.end(), 0);
	std::mt19937 rng(seed);
	int next = 0;
	splitRecursive(p, idx, std::max(2, branching), std::max(1, leaf_points),
	               rng, leaf, next);
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
