#include <forest_slam/cluster/hierarchical_kmeans.h>
#include <forest_slam/core/config.h>
#include <forest_slam/core/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

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
	FS_LOAD(c, s, threads);
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
	if (threads < 1 || threads > 64)
		throw core::ConfigError(where + "threads must be in [1, 64]");
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
	c.write(s, "threads", threads);
}

namespace
{
/** The points in structure-of-arrays form, permuted together with the
 * point indices so that every range being split is contiguous: the
 * distance loops then read contiguous floats, with no gather. */
struct Points
{
	std::vector<float> x, y, z;
	std::vector<uint32_t> idx;  ///< input index of each slot
};

/** Buffers reused by every split of one clustering. */
struct SplitScratch
{
	std::vector<float> d2, tx, ty, tz;
	std::vector<int32_t> lab;
	std::vector<uint8_t> assign;
	std::vector<uint32_t> tidx;

	/** Room for a split of up to n points. */
	void resize(size_t n);
};

/** Bounding box of a group. */
struct Box
{
	Eigen::Vector3f lo, hi;
	float diagonal2() const { return (hi - lo).squaredNorm(); }
};

/** Centres of one k-means split, and the assignment of its points. */
struct Centres
{
	float x[16], y[16], z[16];
	int k = 0;

	/** Nearest centre of each of the n points into lab (ties: the lower
	 * centre). Four points per SSE2 instruction, with the same float
	 * expressions (so the same labels) as the scalar loop for the rest. */
	void nearest(const float* X, const float* Y, const float* Z, size_t n,
	             int32_t* lab) const
	{
		size_t i = 0;
#if defined(__SSE2__)
		for (; i + 4 <= n; i += 4)
		{
			const __m128 px = _mm_loadu_ps(X + i), py = _mm_loadu_ps(Y + i),
			             pz = _mm_loadu_ps(Z + i);
			auto dist = [&](int c)
			{
				const __m128 dx = _mm_sub_ps(px, _mm_set1_ps(x[c]));
				const __m128 dy = _mm_sub_ps(py, _mm_set1_ps(y[c]));
				const __m128 dz = _mm_sub_ps(pz, _mm_set1_ps(z[c]));
				return _mm_add_ps(
				    _mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)),
				    _mm_mul_ps(dz, dz));
			};
			__m128 best = dist(0);
			__m128i best_c = _mm_setzero_si128();
			for (int c = 1; c < k; c++)
			{
				const __m128 d = dist(c);
				const __m128i closer = _mm_castps_si128(_mm_cmplt_ps(d, best));
				best = _mm_min_ps(d, best);
				best_c = _mm_or_si128(_mm_and_si128(closer, _mm_set1_epi32(c)),
				                      _mm_andnot_si128(closer, best_c));
			}
			_mm_storeu_si128(reinterpret_cast<__m128i*>(lab + i), best_c);
		}
#endif
		for (; i < n; i++)
		{
			float best_d = (X[i] - x[0]) * (X[i] - x[0]) +
			               (Y[i] - y[0]) * (Y[i] - y[0]) +
			               (Z[i] - z[0]) * (Z[i] - z[0]);
			int32_t best = 0;
			for (int c = 1; c < k; c++)
			{
				const float d = (X[i] - x[c]) * (X[i] - x[c]) +
				                (Y[i] - y[c]) * (Y[i] - y[c]) +
				                (Z[i] - z[c]) * (Z[i] - z[c]);
				if (d < best_d) best_d = d, best = c;
			}
			lab[i] = best;
		}
	}
};

/** k-means of the n points X, Y, Z: farthest-point initialisation from the
 * first point (deterministic; spreads centres along elongated structures
 * such as stems and branches), then Lloyd steps until the assignment no
 * longer changes. `assign` receives the last assignment. */
Centres lloyd(const float* X, const float* Y, const float* Z, size_t n, int k,
              int iterations, float* d2, int32_t* lab, uint8_t* assign)
{
	Centres C;
	k = static_cast<int>(std::min<size_t>(k, n));
	C.x[0] = X[0], C.y[0] = Y[0], C.z[0] = Z[0];
	C.k = 1;
	std::fill(d2, d2 + n, std::numeric_limits<float>::max());
	while (C.k < k)
	{
		const float qx = C.x[C.k - 1], qy = C.y[C.k - 1], qz = C.z[C.k - 1];
		size_t far = 0;
		float far_d = -1;
		for (size_t i = 0; i < n; i++)
		{
			const float dx = X[i] - qx, dy = Y[i] - qy, dz = Z[i] - qz;
			const float d = std::min(d2[i], dx * dx + dy * dy + dz * dz);
			d2[i] = d;
			if (d > far_d) far_d = d, far = i;
		}
		if (far_d <= 0) break;  // all points identical
		C.x[C.k] = X[far], C.y[C.k] = Y[far], C.z[C.k] = Z[far];
		C.k++;
	}
	std::fill(assign, assign + n, 0);
	for (int it = 0; it < iterations; it++)
	{
		bool changed = false;
		float sx[16] = {0}, sy[16] = {0}, sz[16] = {0};
		uint32_t cnt[16] = {0};
		C.nearest(X, Y, Z, n, lab);
		for (size_t i = 0; i < n; i++)
		{
			const uint8_t best = static_cast<uint8_t>(lab[i]);
			changed |= assign[i] != best;
			assign[i] = best;
			sx[best] += X[i], sy[best] += Y[i], sz[best] += Z[i];
			cnt[best]++;
		}
		if (!changed && it > 0) break;
		for (int c = 0; c < C.k; c++)
			if (cnt[c] > 0)
			{
				const float inv = 1.0f / static_cast<float>(cnt[c]);
				C.x[c] = sx[c] * inv, C.y[c] = sy[c] * inv,
				C.z[c] = sz[c] * inv;
			}
	}
	return C;
}

/** Larger ranges find their centres on an evenly strided sample of this many
 * points, then assign every point once: the top splits of a scan are coarse
 * cuts that a sample places as well, at a fraction of the distances. */
constexpr size_t kSampleSize = 1024;

/** One k-means split of slots [begin, end) in place: on return the range is
 * partitioned into contiguous groups, `bounds` holds their ends and `boxes`
 * their bounding boxes. */
void kmeansSplit(Points& P, size_t begin, size_t end, int k, int iterations,
                 std::vector<size_t>& bounds, std::vector<Box>& boxes,
                 SplitScratch& S)
{
	const size_t n = end - begin;
	const float* X = P.x.data() + begin;
	const float* Y = P.y.data() + begin;
	const float* Z = P.z.data() + begin;
	uint8_t* assign = S.assign.data();
	Centres C;
	if (n <= kSampleSize)
		C = lloyd(X, Y, Z, n, k, iterations, S.d2.data(), S.lab.data(), assign);
	else
	{
		float* sx = S.tx.data();
		float* sy = S.ty.data();
		float* sz = S.tz.data();
		for (size_t j = 0; j < kSampleSize; j++)
		{
			const size_t i = j * n / kSampleSize;
			sx[j] = X[i], sy[j] = Y[i], sz[j] = Z[i];
		}
		C = lloyd(sx, sy, sz, kSampleSize, k, iterations, S.d2.data(),
		          S.lab.data(), assign);
		C.nearest(X, Y, Z, n, S.lab.data());
		for (size_t i = 0; i < n; i++)
			assign[i] = static_cast<uint8_t>(S.lab[i]);
	}
	k = C.k;
	// Stable partition by assignment (counting sort), with the boxes.
	size_t start[17] = {0};
	for (size_t i = 0; i < n; i++) start[assign[i] + 1]++;
	for (int c = 0; c < k; c++) start[c + 1] += start[c];
	std::copy(X, X + n, S.tx.data());
	std::copy(Y, Y + n, S.ty.data());
	std::copy(Z, Z + n, S.tz.data());
	S.tidx.assign(P.idx.begin() + begin, P.idx.begin() + end);
	size_t pos[16];
	Box box[16];
	for (int c = 0; c < k; c++)
	{
		pos[c] = begin + start[c];
		box[c].lo.setConstant(std::numeric_limits<float>::max());
		box[c].hi.setConstant(-std::numeric_limits<float>::max());
	}
	for (size_t i = 0; i < n; i++)
	{
		const int c = assign[i];
		const size_t o = pos[c]++;
		const Eigen::Vector3f q(S.tx[i], S.ty[i], S.tz[i]);
		P.x[o] = q.x(), P.y[o] = q.y(), P.z[o] = q.z();
		P.idx[o] = S.tidx[i];
		box[c].lo = box[c].lo.cwiseMin(q);
		box[c].hi = box[c].hi.cwiseMax(q);
	}
	bounds.clear();
	boxes.clear();
	for (int c = 0; c < k; c++)
		if (start[c + 1] > start[c])
		{
			bounds.push_back(begin + start[c + 1]);
			boxes.push_back(box[c]);
		}
}

void SplitScratch::resize(size_t n)
{
	for (auto* v : {&d2, &tx, &ty, &tz}) v->resize(std::max(n, kSampleSize));
	lab.resize(std::max(n, kSampleSize));
	assign.resize(n);
}

/** Ranges of points being split, with their bounding boxes. */
struct Range
{
	size_t b, e;
	Box box;
};
using Leaves = std::vector<std::pair<size_t, size_t>>;

/** Small enough (points and extent) to be a cluster. */
bool isLeaf(const Range& r, const ClusterOptions& opts)
{
	const float max_extent2 = static_cast<float>(opts.max_cluster_extent_m *
	                                             opts.max_cluster_extent_m);
	return r.e - r.b <= static_cast<size_t>(opts.max_cluster_points) &&
	       (opts.max_cluster_extent_m <= 0 || r.e - r.b < 2 ||
	        r.box.diagonal2() <= max_extent2);
}

/** Splits `root` down to clusters, depth-first with an explicit stack;
 * appends the leaves in the order the stack visits them. */
void splitDown(Points& P, const Range& root, const ClusterOptions& opts,
               SplitScratch& S, Leaves& leaves)
{
	std::vector<Range> stack = {root};
	std::vector<size_t> bounds;
	std::vector<Box> boxes;
	while (!stack.empty())
	{
		const Range r = stack.back();
		stack.pop_back();
		if (isLeaf(r, opts))
		{
			leaves.push_back({r.b, r.e});
			continue;
		}
		kmeansSplit(P, r.b, r.e, opts.branching_factor, opts.kmeans_iterations,
		            bounds, boxes, S);
		if (bounds.size() <= 1)
		{
			leaves.push_back({r.b, r.e});  // cannot split (identical points)
			continue;
		}
		size_t s = r.b;
		for (size_t g = 0; g < bounds.size(); g++)
		{
			stack.push_back({s, bounds[g], boxes[g]});
			s = bounds[g];
		}
	}
}

/** Fewer points than this are split on the caller's thread only: waking a
 * helper costs microseconds, the split of a small scan not much more. */
constexpr size_t kParallelPoints = 4096;
}  // namespace

ClusterLabels hierarchicalKMeans(const std::vector<Eigen::Vector3f>& pts,
                                 const ClusterOptions& opts)
{
	ClusterLabels out;
	out.cluster.assign(pts.size(), -1);
	out.range_m.resize(pts.size());
	out.cluster_size.assign(pts.size(), 0);
	Points P;
	P.idx.reserve(pts.size());
	for (uint32_t i = 0; i < pts.size(); i++)
	{
		out.range_m[i] = pts[i].norm();
		if (pts[i].allFinite()) P.idx.push_back(i);
	}
	if (P.idx.empty()) return out;
	const auto& idx = P.idx;
	const size_t N = idx.size();
	P.x.resize(N), P.y.resize(N), P.z.resize(N);
	Box all{pts[idx[0]], pts[idx[0]]};
	for (size_t i = 0; i < N; i++)
	{
		const auto& q = pts[idx[i]];
		P.x[i] = q.x(), P.y[i] = q.y(), P.z[i] = q.z();
		all.lo = all.lo.cwiseMin(q);
		all.hi = all.hi.cwiseMax(q);
	}
	SplitScratch scratch;
	scratch.resize(N);

	// The root's split, then its groups split down on `threads` threads
	// (each range is partitioned in place, the groups are disjoint); the
	// leaves are concatenated in the order one depth-first stack visits
	// them, so the clusters do not depend on the thread count.
	const Range root{0, N, all};
	Leaves leaves;
	std::vector<size_t> bounds;
	std::vector<Box> boxes;
	if (opts.threads < 2 || N < kParallelPoints || isLeaf(root, opts))
		splitDown(P, root, opts, scratch, leaves);
	else
	{
		kmeansSplit(P, 0, N, opts.branching_factor, opts.kmeans_iterations,
		            bounds, boxes, scratch);
		if (bounds.size() <= 1) bounds = {N}, boxes = {all};  // one leaf
		std::vector<Range> groups;
		for (size_t g = 0, s = 0; g < bounds.size(); s = bounds[g++])
			groups.push_back({s, bounds[g], boxes[g]});
		std::vector<Leaves> part(groups.size());
		const int workers = std::min<int>(opts.threads, groups.size());
		std::vector<SplitScratch> extra_scratch(std::max(0, workers - 1));
		std::vector<char> sized(extra_scratch.size(), 0);
		core::parallelRanges(groups.size(), workers, 1,
		                     [&](size_t b, size_t e, int w)
		                     {
			                     SplitScratch& S =
			                         w == 0 ? scratch : extra_scratch[w - 1];
			                     if (w > 0 && !sized[w - 1])
				                     S.resize(N), sized[w - 1] = 1;
			                     for (size_t g = b; g < e; g++)
				                     splitDown(P, groups[g], opts, S, part[g]);
		                     });
		// A stack pops the last group first.
		for (size_t g = groups.size(); g-- > 0;)
			leaves.insert(leaves.end(), part[g].begin(), part[g].end());
	}

	// Leaves -> clusters; then merge the small ones into the nearest big one.
	const size_t L = leaves.size();
	std::vector<Eigen::Vector3f> cen(L);
	std::vector<uint32_t> size(L);
	for (size_t l = 0; l < L; l++)
	{
		Eigen::Vector3f s = Eigen::Vector3f::Zero();
		for (size_t i = leaves[l].first; i < leaves[l].second; i++)
			s += Eigen::Vector3f(P.x[i], P.y[i], P.z[i]);
		size[l] = static_cast<uint32_t>(leaves[l].second - leaves[l].first);
		cen[l] = s / static_cast<float>(size[l]);
	}
	std::vector<int32_t> target(L);
	std::iota(target.begin(), target.end(), 0);
	// Big clusters hashed by centroid on a grid: the nearest one within the
	// merge distance is in the 8 cells nearest the small one's centroid.
	const float md = static_cast<float>(opts.max_merge_distance_m);
	const uint32_t min_pts = static_cast<uint32_t>(opts.min_cluster_points);
	if (md > 0)
	{
		// Cells twice the merge distance wide: the ball of radius md around
		// a centroid touches at most two cells per axis (8, not 27).
		const float inv_cell = 0.5f / md;
		auto cellOf = [&](const Eigen::Vector3f& p)
		{
			return Eigen::Vector3f(std::floor(p.x() * inv_cell),
			                       std::floor(p.y() * inv_cell),
			                       std::floor(p.z() * inv_cell));
		};
		auto cellKey = [](const Eigen::Vector3f& c, int dx, int dy, int dz)
		{
			constexpr int64_t m = (1 << 21) - 1;
			return ((static_cast<int64_t>(c.x()) + dx) & m) << 42 |
			       ((static_cast<int64_t>(c.y()) + dy) & m) << 21 |
			       ((static_cast<int64_t>(c.z()) + dz) & m);
		};
		// (cell key, cluster) sorted, and an open-addressing table from a
		// cell key to its run in that list: flat, no per-cell allocation.
		std::vector<std::pair<int64_t, int32_t>> grid;
		for (size_t l = 0; l < L; l++)
			if (size[l] >= min_pts)
				grid.push_back({cellKey(cellOf(cen[l]), 0, 0, 0),
				                static_cast<int32_t>(l)});
		std::sort(grid.begin(), grid.end());
		struct Slot
		{
			int64_t key;
			uint32_t begin, end;  ///< end == 0: empty slot
		};
		int bits = 4;
		while ((size_t(1) << bits) < 2 * grid.size()) bits++;
		const size_t cap = size_t(1) << bits;
		std::vector<Slot> table(cap, Slot{0, 0, 0});
		// Fibonacci hashing: the top bits of the product mix every key bit.
		auto slotOf = [&](int64_t key)
		{
			return static_cast<size_t>(
			    (static_cast<uint64_t>(key) * 0x9E3779B97F4A7C15ull) >>
			    (64 - bits));
		};
		for (size_t g = 0; g < grid.size();)
		{
			size_t e = g + 1;
			while (e < grid.size() && grid[e].first == grid[g].first) e++;
			size_t h = slotOf(grid[g].first);
			while (table[h].end != 0) h = (h + 1) & (cap - 1);
			table[h] = {grid[g].first, static_cast<uint32_t>(g),
			            static_cast<uint32_t>(e)};
			g = e;
		}
		for (size_t l = 0; l < L; l++)
		{
			if (size[l] >= min_pts) continue;
			float best = md * md;
			int32_t best_l = -1;
			const Eigen::Vector3f cell = cellOf(cen[l]);
			// The neighbour cell on the side of the centroid, per axis.
			const Eigen::Vector3f f = cen[l] * inv_cell - cell;
			const int sx = f.x() < 0.5f ? -1 : 1, sy = f.y() < 0.5f ? -1 : 1,
			          sz = f.z() < 0.5f ? -1 : 1;
			for (int dx : {0, sx})
				for (int dy : {0, sy})
					for (int dz : {0, sz})
					{
						const int64_t key = cellKey(cell, dx, dy, dz);
						size_t h = slotOf(key);
						while (table[h].end != 0 && table[h].key != key)
							h = (h + 1) & (cap - 1);
						for (uint32_t g = table[h].begin; g < table[h].end; g++)
						{
							const int32_t m = grid[g].second;
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
