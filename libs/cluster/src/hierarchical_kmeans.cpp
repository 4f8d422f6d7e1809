#include <forest_slam/cluster/hierarchical_kmeans.h>
#include <forest_slam/core/config.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <unordered_map>

namespace forest_slam::cluster
{
void ClusterOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                        const std::string& s)
{
	FS_LOAD(c, s, branching_factor);
	FS_LOAD(c, s, max_cluster_points);
	FS_LOAD(c, s, min_cluster_points);
	FS_LOAD(c, s, kmeans_iterations);
	FS_LOAD(c, s, max_merge_distance_m);
	FS_LOAD(c, s, max_cluster_extent_m);
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
	if (!(max_cluster_extent_m >= 0))
		throw core::ConfigError(where + "max_cluster_extent_m must be >= 0");
	if (!(max_merge_distance_m >= 0))
		throw core::ConfigError(where + "max_merge_distance_m must be >= 0");
}

void ClusterOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                      const std::string& s) const
{
	c.write(s, "branching_factor", branching_factor);
	c.write(s, "max_cluster_points", max_cluster_points);
	c.write(s, "min_cluster_points", min_cluster_points);
	c.write(s, "kmeans_iterations", kmeans_iterations);
	c.write(s, "max_merge_distance_m", max_merge_distance_m);
	c.write(s, "max_cluster_extent_m", max_cluster_extent_m);
}

namespace
{
/** Buffers reused by every split of one clustering. */
struct SplitScratch
{
	std::vector<Eigen::Vector3f> local;  // the range's points, contiguous
	std::vector<float> d2;
	std::vector<uint8_t> assign;
	std::vector<uint32_t> tmp;
};

/** One k-means split of the points idx[begin,end) in place: on return the
 * range is partitioned into contiguous groups, `bounds` holds their ends. */
void kmeansSplit(const std::vector<Eigen::Vector3f>& pts,
                 std::vector<uint32_t>& idx, size_t begin, size_t end, int k,
                 int iterations, std::vector<size_t>& bounds, SplitScratch& S)
{
	const size_t n = end - begin;
	k = static_cast<int>(std::min<size_t>(k, n));
	S.local.resize(n);
	for (size_t i = 0; i < n; i++) S.local[i] = pts[idx[begin + i]];
	const auto& P = S.local;
	// Farthest-point initialisation from the first point: deterministic and
	// spreads centres along elongated structures (stems, branches).
	Eigen::Vector3f centres[16];
	int nc = 1;
	centres[0] = P[0];
	S.d2.assign(n, std::numeric_limits<float>::max());
	while (nc < k)
	{
		size_t best = 0;
		float best_d = -1;
		for (size_t i = 0; i < n; i++)
		{
			S.d2[i] = std::min(S.d2[i], (P[i] - centres[nc - 1]).squaredNorm());
			if (S.d2[i] > best_d)
			{
				best_d = S.d2[i];
				best = i;
			}
		}
		if (best_d <= 0) break;  // all points identical
		centres[nc++] = P[best];
	}
	k = nc;
	S.assign.assign(n, 0);
	for (int it = 0; it < iterations; it++)
	{
		bool changed = false;
		Eigen::Vector3f sum[16];
		int cnt[16] = {0};
		for (int c = 0; c < k; c++) sum[c].setZero();
		for (size_t i = 0; i < n; i++)
		{
			int best = 0;
			float best_d = (P[i] - centres[0]).squaredNorm();
			for (int c = 1; c < k; c++)
			{
				const float d = (P[i] - centres[c]).squaredNorm();
				if (d < best_d)
				{
					best_d = d;
					best = c;
				}
			}
			changed |= S.assign[i] != best;
			S.assign[i] = static_cast<uint8_t>(best);
			sum[best] += P[i];
			cnt[best]++;
		}
		if (!changed && it > 0) break;
		for (int c = 0; c < k; c++)
			if (cnt[c] > 0) centres[c] = sum[c] / static_cast<float>(cnt[c]);
	}
	// Stable partition by assignment (counting sort).
	size_t start[17] = {0};
	for (size_t i = 0; i < n; i++) start[S.assign[i] + 1]++;
	for (int c = 0; c < k; c++) start[c + 1] += start[c];
	S.tmp.assign(idx.begin() + begin, idx.begin() + end);
	size_t pos[16];
	for (int c = 0; c < k; c++) pos[c] = start[c];
	for (size_t i = 0; i < n; i++) idx[begin + pos[S.assign[i]]++] = S.tmp[i];
	bounds.clear();
	for (int c = 0; c < k; c++)
		if (start[c + 1] > start[c]) bounds.push_back(begin + start[c + 1]);
}

/** Squared diagonal of the bounding box of idx[begin, end). */
float extentSquared(const std::vector<Eigen::Vector3f>& pts,
                    const std::vector<uint32_t>& idx, size_t begin, size_t end)
{
	Eigen::Vector3f lo = pts[idx[begin]], hi = lo;
	for (size_t i = begin + 1; i < end; i++)
	{
		lo = lo.cwiseMin(pts[idx[i]]);
		hi = hi.cwiseMax(pts[idx[i]]);
	}
	return (hi - lo).squaredNorm();
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
	SplitScratch scratch;
	const float max_extent2 = static_cast<float>(opts.max_cluster_extent_m *
	                                             opts.max_cluster_extent_m);
	while (!stack.empty())
	{
		const auto [b, e] = stack.back();
		stack.pop_back();
		if (e - b <= static_cast<size_t>(opts.max_cluster_points) &&
		    (opts.max_cluster_extent_m <= 0 || e - b < 2 ||
		     extentSquared(pts, idx, b, e) <= max_extent2))
		{
			leaves.push_back({b, e});
			continue;
		}
		kmeansSplit(pts, idx, b, e, opts.branching_factor,
		            opts.kmeans_iterations, bounds, scratch);
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
		for (size_t i = leaves[l].first; i < leaves[l].second; i++)
			s += pts[idx[i]];
		size[l] = static_cast<uint32_t>(leaves[l].second - leaves[l].first);
		cen[l] = s / static_cast<float>(size[l]);
	}
	std::vector<int32_t> target(L);
	std::iota(target.begin(), target.end(), 0);
	// Big clusters hashed by centroid on a grid of the merge distance: the
	// nearest one within it is in the 27 cells around.
	const float md = static_cast<float>(opts.max_merge_distance_m);
	const uint32_t min_pts = static_cast<uint32_t>(opts.min_cluster_points);
	if (md > 0)
	{
		auto cellKey = [&](const Eigen::Vector3f& p, int dx, int dy, int dz)
		{
			const int64_t x = static_cast<int64_t>(std::floor(p.x() / md)) + dx,
			              y = static_cast<int64_t>(std::floor(p.y() / md)) + dy,
			              z = static_cast<int64_t>(std::floor(p.z() / md)) + dz;
			return (x * 73856093) ^ (y * 19349663) ^ (z * 83492791);
		};
		std::unordered_map<int64_t, std::vector<int32_t>> grid;
		for (size_t l = 0; l < L; l++)
			if (size[l] >= min_pts)
				grid[cellKey(cen[l], 0, 0, 0)].push_back(
				    static_cast<int32_t>(l));
		for (size_t l = 0; l < L; l++)
		{
			if (size[l] >= min_pts) continue;
			float best = md * md;
			int32_t best_l = -1;
			for (int dx = -1; dx <= 1; dx++)
				for (int dy = -1; dy <= 1; dy++)
					for (int dz = -1; dz <= 1; dz++)
					{
						const auto it = grid.find(cellKey(cen[l], dx, dy, dz));
						if (it == grid.end()) continue;
						for (int32_t m : it->second)
						{
							const float d = (cen[m] - cen[l]).squaredNorm();
							if (d < best || (d == best && m < best_l))
							{
								best = d;
								best_l = m;
							}
						}
					}
			if (best_l >= 0) target[l] = best_l;
		}
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
		if (out.cluster[i] >= 0)
			out.cluster_size[i] = out.sizes[out.cluster[i]];
	return out;
}

}  // namespace forest_slam::cluster
