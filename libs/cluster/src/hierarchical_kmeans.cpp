#include <forest_slam/cluster/hierarchical_kmeans.h>
#include <forest_slam/core/config.h>

#include <algorithm>
#include <limits>
#include <numeric>

namespace forest_slam::cluster
{
void ClusterOptions::loadFromConfigFile(
	const mrpt::config::CConfigFileBase& c, const std::string& s)
{
	FS_LOAD(c, s, branching_factor);
	FS_LOAD(c, s, max_cluster_points);
	FS_LOAD(c, s, min_cluster_points);
	FS_LOAD(c, s, kmeans_iterations);
	FS_LOAD(c, s, max_merge_distance_m);
	const std::string where = core::configOrigin(c) + ": [" + s + "] ";
	if (branching_factor < 2 || branching_factor > 16)
		throw core::ConfigError(where + "branching_factor must be in [2, 16]");
	if (max_cluster_points < 2)
		throw core::ConfigError(where + "max_cluster_points must be >= 2");
	if (min_cluster_points < 1 || min_cluster_points > max_cluster_points)
		throw core::ConfigError(
			where + "min_cluster_points must be in [1, max_cluster_points]");
	if (kmeans_iterations < 1)
		throw core::ConfigError(where + "kmeans_iterations must be >= 1");
	if (!(max_merge_distance_m >= 0))
		throw core::ConfigError(where + "max_merge_distance_m must be >= 0");
}

void ClusterOptions::saveToConfigFile(
	mrpt::config::CConfigFileBase& c, const std::string& s) const
{
	c.write(s, "branching_factor", branching_factor);
	c.write(s, "max_cluster_points", max_cluster_points);
	c.write(s, "min_cluster_points", min_cluster_points);
	c.write(s, "kmeans_iterations", kmeans_iterations);
	c.write(s, "max_merge_distance_m", max_merge_distance_m);
}

namespace
{
/** One k-means split of the points idx[begin,end) in place: on return the
 * range is partitioned into contiguous groups, `bounds` holds their ends. */
void kmeansSplit(const std::vector<Eigen::Vector3f>& pts, std::vector<uint32_t>& idx,
				 size_t begin, size_t end, int k, int iterations,
				 std::vector<size_t>& bounds)
{
	const size_t n = end - begin;
	k = static_cast<int>(std::min<size_t>(k, n));
	// Farthest-point initialisation from the first point: deterministic and
	// spreads centres along elongated structures (stems, branches).
	std::vector<Eigen::Vector3f> centres;
	centres.push_back(pts[idx[begin]]);
	std::vector<float> d2(n, std::numeric_limits<float>::max());
	while (static_cast<int>(centres.size()) < k)
	{
		size_t best = 0;
		float best_d = -1;
		for (size_t i = 0; i < n; i++)
		{
			d2[i] = std::min(d2[i], (pts[idx[begin + i]] - centres.back()).squaredNorm());
			if (d2[i] > best_d)
			{
				best_d = d2[i];
				best = i;
			}
		}
		if (best_d <= 0) break;	 // all points identical
		centres.push_back(pts[idx[begin + best]]);
	}
	k = static_cast<int>(centres.size());
	std::vector<int> assign(n, 0);
	for (int it = 0; it < iterations; it++)
	{
		bool changed = false;
		for (size_t i = 0; i < n; i++)
		{
			const auto& p = pts[idx[begin + i]];
			int best = 0;
			float best_d = std::numeric_limits<float>::max();
			for (int c = 0; c < k; c++)
			{
				const float d = (p - centres[c]).squaredNorm();
				if (d < best_d)
				{
					best_d = d;
					best = c;
				}
			}
			changed |= assign[i] != best;
			assign[i] = best;
		}
		if (!changed && it > 0) break;
		std::vector<Eigen::Vector3f> sum(k, Eigen::Vector3f::Zero());
		std::vector<int> cnt(k, 0);
		for (size_t i = 0; i < n; i++)
		{
			sum[assign[i]] += pts[idx[begin + i]];
			cnt[assign[i]]++;
		}
		for (int c = 0; c < k; c++)
			if (cnt[c] > 0) centres[c] = sum[c] / static_cast<float>(cnt[c]);
	}
	// Stable partition by assignment.
	std::vector<uint32_t> tmp(idx.begin() + begin, idx.begin() + end);
	std::vector<int> order(n);
	std::iota(order.begin(), order.end(), 0);
	std::stable_sort(order.begin(), order.end(),
					 [&](int a, int b) { return assign[a] < assign[b]; });
	for (size_t i = 0; i < n; i++) idx[begin + i] = tmp[order[i]];
	bounds.clear();
	for (size_t i = 1; i <= n; i++)
		if (i == n || assign[order[i]] != assign[order[i - 1]]) bounds.push_back(begin + i);
}
}  // namespace

ClusterLabels hierarchicalKMeans(const std::vector<Eigen::Vector3f>& pts,
								 const ClusterOptions& opts)
{
	ClusterLabels out;
	out.cluster.assign(pts.size(), -1);
	out.range_m.resize(pts.size());
	out.cluster_size.assign(pts.size(), 0);
	std::vector<uint32_t> idx;
	idx.reserve(pts.size());
	for (uint32_t i = 0; i < pts.size(); i++)
	{
		out.range_m[i] = pts[i].norm();
		if (pts[i].allFinite()) idx.push_back(i);
	}
	if (idx.empty()) return out;

	// Depth-first recursion with an explicit stack of [begin, end) ranges.
	std::vector<std::pair<size_t, size_t>> stack = {{0, idx.size()}};
	std::vector<std::pair<size_t, size_t>> leaves;
	std::vector<size_t> bounds;
	while (!stack.empty())
	{
		const auto [b, e] = stack.back();
		stack.pop_back();
		if (e - b <= static_cast<size_t>(opts.max_cluster_points))
		{
			leaves.push_back({b, e});
			continue;
		}
		kmeansSplit(pts, idx, b, e, opts.branching_factor, opts.kmeans_iterations, bounds);
		if (bounds.size() <= 1)
		{
			leaves.push_back({b, e});  // cannot split (identical points)
			continue;
		}
		size_t s = b;
		for (size_t bend : bounds)
		{
			stack.push_back({s, bend});
			s = bend;
		}
	}

	// Leaves -> clusters; then merge the small ones into the nearest big one.
	const size_t L = leaves.size();
	std::vector<Eigen::Vector3f> cen(L);
	std::vector<uint32_t> size(L);
	for (size_t l = 0; l < L; l++)
	{
		Eigen::Vector3f s = Eigen::Vector3f::Zero();
		for (size_t i = leaves[l].first; i < leaves[l].second; i++) s += pts[idx[i]];
		size[l] = static_cast<uint32_t>(leaves[l].second - leaves[l].first);
		cen[l] = s / static_cast<float>(size[l]);
	}
	std::vector<int32_t> target(L);
	std::iota(target.begin(), target.end(), 0);
	const float max_d2 = static_cast<float>(opts.max_merge_distance_m * opts.max_merge_distance_m);
	for (size_t l = 0; l < L; l++)
	{
		if (size[l] >= static_cast<uint32_t>(opts.min_cluster_points)) continue;
		float best = max_d2;
		int32_t best_l = -1;
		for (size_t m = 0; m < L; m++)
		{
			if (m == l || size[m] < static_cast<uint32_t>(opts.min_cluster_points)) continue;
			const float d = (cen[m] - cen[l]).squaredNorm();
			if (d < best)
			{
				best = d;
				best_l = static_cast<int32_t>(m);
			}
		}
		if (best_l >= 0) target[l] = best_l;
	}
	// Compact ids in leaf order (deterministic).
	std::vector<int32_t> id_of(L, -1);
	for (size_t l = 0; l < L; l++)
	{
		const int32_t t = target[l];
		if (id_of[t] < 0)
		{
			id_of[t] = static_cast<int32_t>(out.sizes.size());
			out.sizes.push_back(0);
			out.centroids.push_back(Eigen::Vector3f::Zero());
		}
	}
	for (size_t l = 0; l < L; l++)
	{
		const int32_t id = id_of[target[l]];
		for (size_t i = leaves[l].first; i < leaves[l].second; i++)
		{
			out.cluster[idx[i]] = id;
			out.centroids[id] += pts[idx[i]];
		}
		out.sizes[id] += size[l];
	}
	for (size_t c = 0; c < out.sizes.size(); c++)
		out.centroids[c] /= static_cast<float>(out.sizes[c]);
	for (size_t i = 0; i < pts.size(); i++)
		if (out.cluster[i] >= 0) out.cluster_size[i] = out.sizes[out.cluster[i]];
	return out;
}

}  // namespace forest_slam::cluster
