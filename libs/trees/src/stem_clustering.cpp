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
	// Within a square the points are grouped by leaf: two groups whose
	// leaves are joined already are skipped whole, and the first pair within
	// link_m joins them (the clusters are the connected leaves, found in any
	// order). The squares are keyed by (x, y) packed in one word (offset
	// binary: the order of the pair).
	struct Keyed
	{
		uint64_t square;
		int leaf;
		uint32_t i;
		bool operator<(const Keyed& o) const
		{
			return std::tie(square, leaf, i) < std::tie(o.square, o.leaf, o.i);
		}
	};
	auto cellOf = [&](double v) { return int64_t(std::floor(v / link_m)); };
	auto pack = [](int64_t x, int64_t y)
	{
		return uint64_t(uint32_t(int32_t(x)) ^ 0x80000000u) << 32 |
		       uint64_t(uint32_t(int32_t(y)) ^ 0x80000000u);
	};
	std::vector<Keyed> keyed;
	keyed.reserve(p.size());
	for (size_t i = 0; i < p.size(); i++)
		keyed.push_back(
		    {pack(cellOf(p[i].x()), cellOf(p[i].y())), leaf[i], uint32_t(i)});
	std::sort(keyed.begin(), keyed.end());
	struct Group  // the points of one leaf in one square
	{
		int leaf;
		size_t begin, end;  // in keyed
	};
	struct Square
	{
		int64_t x, y;
		size_t begin, end;  // in groups
	};
	std::vector<Group> groups;
	std::vector<Square> sq;
	for (size_t j = 0; j < keyed.size(); j++)
	{
		if (j == 0 || keyed[j].square != keyed[j - 1].square)
		{
			const auto& q = p[keyed[j].i];
			sq.push_back({cellOf(q.x()), cellOf(q.y()), groups.size(), 0});
		}
		if (groups.empty() || keyed[j].square != keyed[j - 1].square ||
		    keyed[j].leaf != keyed[j - 1].leaf)
			groups.push_back({keyed[j].leaf, j, j});
		groups.back().end = j + 1;
		sq.back().end = groups.size();
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
	auto linked = [&](const Group& ga, const Group& gb)
	{
		for (size_t u = ga.begin; u < ga.end; u++)
			for (size_t v = gb.begin; v < gb.end; v++)
				if ((p[keyed[u].i] - p[keyed[v].i]).squaredNorm() <= link2)
					return true;
		return false;
	};
	for (const auto& a : sq)
		for (int dx = 0; dx <= 1; dx++)
			for (int dy = -1; dy <= 1; dy++)
			{
				if (dx == 0 && dy < 0) continue;  // each pair of squares once
				const Square* b =
				    dx == 0 && dy == 0 ? &a : findSquare(a.x + dx, a.y + dy);
				if (!b) continue;
				for (size_t ia = a.begin; ia < a.end; ia++)
					for (size_t ib = (b == &a ? ia + 1 : b->begin); ib < b->end;
					     ib++)
					{
						const Group &ga = groups[ia], &gb = groups[ib];
						if (ga.leaf == gb.leaf) continue;
						const int ra = findRoot(parent, ga.leaf),
						          rb = findRoot(parent, gb.leaf);
						if (ra != rb && linked(ga, gb)) parent[ra] = rb;
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
