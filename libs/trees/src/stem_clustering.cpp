#include <forest_slam/cluster/hierarchical_kmeans.h>
#include <forest_slam/trees/stem_clustering.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <tuple>

namespace forest_slam::trees
{
namespace
{
/** thinToCells merges up to this many sorted runs, and sorts beyond. */
constexpr size_t kMaxMergedRuns = 32;
int findRoot(std::vector<int>& parent, int i)
{
	while (parent[i] != i) i = parent[i] = parent[parent[i]];
	return i;
}
}  // namespace

Points2D thinToCells(const Points2D& p, double cell_m,
                     std::vector<uint32_t>* cell_of)
{
	if (cell_of) cell_of->assign(p.size(), 0);
	std::vector<std::pair<std::pair<int64_t, int64_t>, size_t>> keyed;
	keyed.reserve(p.size());
	for (size_t i = 0; i < p.size(); i++)
		keyed.push_back({{int64_t(std::floor(p[i].x() / cell_m)),
		                  int64_t(std::floor(p[i].y() / cell_m))},
		                 i});
	// The tree layer's slices come as a few sorted runs (one per column
	// read: voxels in key order, a cell no larger than a voxel): merged,
	// not sorted again. Same result either way.
	std::vector<size_t> runs{0};
	for (size_t j = 1; j < keyed.size() && runs.size() <= kMaxMergedRuns; j++)
		if (keyed[j] < keyed[j - 1]) runs.push_back(j);
	if (runs.size() > kMaxMergedRuns)
		std::sort(keyed.begin(), keyed.end());
	else
		for (runs.push_back(keyed.size()); runs.size() > 2;)
		{
			std::vector<size_t> merged{0};
			for (size_t r = 0; r + 2 < runs.size(); r += 2)
			{
				std::inplace_merge(keyed.begin() + runs[r],
				                   keyed.begin() + runs[r + 1],
				                   keyed.begin() + runs[r + 2]);
				merged.push_back(runs[r + 2]);
			}
			if (merged.back() != keyed.size()) merged.push_back(keyed.size());
			runs.swap(merged);
		}
	Points2D out;
	for (size_t j = 0; j < keyed.size();)
	{
		Eigen::Vector2d sum = Eigen::Vector2d::Zero();
		size_t k = j;
		for (; k < keyed.size() && keyed[k].first == keyed[j].first; k++)
		{
			sum += p[keyed[k].second];
			if (cell_of) (*cell_of)[keyed[k].second] = uint32_t(out.size());
		}
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
	// Exact pairs within link_m lie in the same or adjacent link_m squares.
	// Only pairs of points from different leaves matter, and most squares
	// hold one leaf only, so the squares are compared, not searched.
	std::vector<std::tuple<int64_t, int64_t, size_t>> keyed;
	keyed.reserve(p.size());
	for (size_t i = 0; i < p.size(); i++)
		keyed.emplace_back(int64_t(std::floor(p[i].x() / link_m)),
		                   int64_t(std::floor(p[i].y() / link_m)), i);
	std::sort(keyed.begin(), keyed.end());
	struct Square
	{
		int64_t x, y;
		size_t begin, end;
		bool one_leaf;
	};
	std::vector<Square> sq;
	for (size_t j = 0; j < keyed.size();)
	{
		const auto [x, y, i0] = keyed[j];
		size_t k = j;
		bool one = true;
		for (; k < keyed.size() && std::get<0>(keyed[k]) == x &&
		       std::get<1>(keyed[k]) == y;
		     k++)
			one = one && leaf[std::get<2>(keyed[k])] == leaf[i0];
		sq.push_back({x, y, j, k, one});
		j = k;
	}
	auto findSquare = [&](int64_t x, int64_t y) -> const Square*
	{
		const auto it = std::lower_bound(
		    sq.begin(), sq.end(), std::make_pair(x, y),
		    [](const Square& s, const std::pair<int64_t, int64_t>& k)
		    { return std::make_pair(s.x, s.y) < k; });
		return it != sq.end() && it->x == x && it->y == y ? &*it : nullptr;
	};
	const double link2 = link_m * link_m;
	for (const auto& a : sq)
		for (int dx = 0; dx <= 1; dx++)
			for (int dy = -1; dy <= 1; dy++)
			{
				if (dx == 0 && dy < 0) continue;  // each pair of squares once
				const Square* b =
				    dx == 0 && dy == 0 ? &a : findSquare(a.x + dx, a.y + dy);
				if (!b) continue;
				if (a.one_leaf && b->one_leaf &&
				    findRoot(parent, leaf[std::get<2>(keyed[a.begin])]) ==
				        findRoot(parent, leaf[std::get<2>(keyed[b->begin])]))
					continue;
				for (size_t u = a.begin; u < a.end; u++)
				{
					const size_t i = std::get<2>(keyed[u]);
					for (size_t v = (b == &a ? u + 1 : b->begin); v < b->end;
					     v++)
					{
						const size_t j = std::get<2>(keyed[v]);
						if (leaf[i] == leaf[j]) continue;
						const int ra = findRoot(parent, leaf[i]),
						          rb = findRoot(parent, leaf[j]);
						if (ra != rb && (p[i] - p[j]).squaredNorm() <= link2)
							parent[ra] = rb;
					}
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
