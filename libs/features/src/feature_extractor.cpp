#include <forest_slam/core/config.h>
#include <forest_slam/features/feature_extractor.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <numeric>

namespace forest_slam::features
{
void FeatureOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                        const std::string& s)
{
	FS_LOAD(c, s, half_window);
	FS_LOAD(c, s, edge_threshold);
	FS_LOAD(c, s, planar_threshold);
	FS_LOAD(c, s, sectors_per_ring);
	FS_LOAD(c, s, max_edges_per_sector);
	FS_LOAD(c, s, max_planar_per_sector);
	FS_LOAD(c, s, ground_decimation);
	FS_LOAD(c, s, silhouette_gap_m);
	FS_LOAD(c, s, edge_min_linearity);
	FS_LOAD(c, s, planar_from_neighbours);
	core::loadOption(c, s, "range_smoothing_half_window",
	                 range_smoothing.half_window);
	core::loadOption(c, s, "range_smoothing_max_step_m",
	                 range_smoothing.max_step_m);
	const std::string where = core::configOrigin(c) + ": [" + s + "] ";
	if (half_window < 1 || half_window > 20)
		throw core::ConfigError(where + "half_window must be in [1, 20]");
	if (!(planar_threshold < edge_threshold))
		throw core::ConfigError(where +
		                        "planar_threshold must be < edge_threshold");
	if (sectors_per_ring < 1 || max_edges_per_sector < 0 ||
	    max_planar_per_sector < 0)
		throw core::ConfigError(where +
		                        "sector counts must be >= 0 (sectors >= 1)");
	if (!(edge_min_linearity >= 0 && edge_min_linearity < 1))
		throw core::ConfigError(where + "edge_min_linearity must be in [0, 1)");
	if (ground_decimation < 1)
		throw core::ConfigError(where + "ground_decimation must be >= 1");
	if (range_smoothing.half_window < 0 || range_smoothing.half_window > 20)
		throw core::ConfigError(
		    where + "range_smoothing_half_window must be in [0, 20]");
	if (!(range_smoothing.max_step_m > 0))
		throw core::ConfigError(where +
		                        "range_smoothing_max_step_m must be > 0");
}

void FeatureOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                      const std::string& s) const
{
	c.write(s, "half_window", half_window);
	c.write(s, "edge_threshold", edge_threshold);
	c.write(s, "planar_threshold", planar_threshold);
	c.write(s, "sectors_per_ring", sectors_per_ring);
	c.write(s, "max_edges_per_sector", max_edges_per_sector);
	c.write(s, "max_planar_per_sector", max_planar_per_sector);
	c.write(s, "ground_decimation", ground_decimation);
	c.write(s, "silhouette_gap_m", silhouette_gap_m);
	c.write(s, "edge_min_linearity", edge_min_linearity);
	c.write(s, "planar_from_neighbours", planar_from_neighbours);
	c.write(s, "range_smoothing_half_window", range_smoothing.half_window);
	c.write(s, "range_smoothing_max_step_m", range_smoothing.max_step_m);
}

namespace
{
/** Eigenvalues (ascending) of a symmetric 3x3 matrix in closed form (the
 * trigonometric solution of the characteristic cubic): a fraction of an
 * iterative solver's cost, ample for a shape ratio. */
Eigen::Vector3d eigenvalues3(const Eigen::Matrix3d& A)
{
	const double p1 = A(0, 1) * A(0, 1) + A(0, 2) * A(0, 2) + A(1, 2) * A(1, 2);
	const double q = A.trace() / 3;
	const double p2 = (A(0, 0) - q) * (A(0, 0) - q) +
	                  (A(1, 1) - q) * (A(1, 1) - q) +
	                  (A(2, 2) - q) * (A(2, 2) - q) + 2 * p1;
	if (p2 <= 1e-30 * q * q || p2 == 0)
		return Eigen::Vector3d(q, q, q);  // a multiple of the identity
	const double p = std::sqrt(p2 / 6);
	const Eigen::Matrix3d B = (A - q * Eigen::Matrix3d::Identity()) / p;
	const double r = std::clamp(B.determinant() / 2, -1.0, 1.0);
	const double phi = std::acos(r) / 3;
	const double hi = q + 2 * p * std::cos(phi);
	const double lo = q + 2 * p * std::cos(phi + 2 * M_PI / 3);
	return Eigen::Vector3d(lo, 3 * q - hi - lo, hi);
}
/** A deterministic scramble of an index (an integer hash), for an order
 * that favours no position. */
inline uint32_t scatterHash(uint32_t x)
{
	x ^= x >> 16;
	x *= 0x7feb352dU;
	x ^= x >> 15;
	x *= 0x846ca68bU;
	x ^= x >> 16;
	return x;
}
}  // namespace

RingLines ringLines(const std::vector<FeatureInputPoint>& pts)
{
	RingLines out;
	int max_ring = -1;
	for (const auto& p : pts) max_ring = std::max<int>(max_ring, p.ring);
	// A counting sort by ring keeps the input order within a ring, which is
	// firing order for an unpacked scan (checked below; sorted only if not).
	out.start.assign(max_ring + 2, 0);
	for (const auto& p : pts)
		if (p.xyz.allFinite()) out.start[p.ring + 1]++;
	for (int r = 0; r <= max_ring; r++) out.start[r + 1] += out.start[r];
	out.index.resize(out.start.back());
	std::vector<uint32_t> pos(out.start.begin(), out.start.end() - 1);
	for (uint32_t i = 0; i < pts.size(); i++)
		if (pts[i].xyz.allFinite()) out.index[pos[pts[i].ring]++] = i;
	auto byColumn = [&](uint32_t a, uint32_t b)
	{ return pts[a].column < pts[b].column; };
	for (int r = 0; r <= max_ring; r++)
	{
		uint32_t* line = out.index.data() + out.start[r];
		uint32_t* end = out.index.data() + out.start[r + 1];
		if (!std::is_sorted(line, end, byColumn))
			std::stable_sort(line, end, byColumn);
	}
	return out;
}

Features extractFeatures(const std::vector<FeatureInputPoint>& pts,
                         const FeatureOptions& o)
{
	return extractFeatures(pts, ringLines(pts), o);
}

Features extractFeatures(const std::vector<FeatureInputPoint>& pts,
                         const RingLines& lines, const FeatureOptions& o)
{
	Features out;
	out.smoothness.assign(pts.size(), -1.f);
	if (pts.empty()) return out;
	const int max_ring = lines.rings() - 1;
	const std::vector<uint32_t>& ring_start = lines.start;
	const std::vector<uint32_t>& line_of = lines.index;

	// Shape of every cluster: edges only on linear ones (stems, branches);
	// the scattered returns of a shrub or foliage look sharp to the
	// smoothness everywhere but are no stable edge.
	std::vector<uint8_t> edge_ok;
	std::vector<Eigen::Matrix<double, 10, 1>> mom;
	if (o.edge_min_linearity > 0)
	{
		int32_t max_id = -1;
		for (const auto& p : pts) max_id = std::max(max_id, p.cluster);
		mom.assign(max_id + 1, Eigen::Matrix<double, 10, 1>::Zero());
		for (const auto& p : pts)
			if (p.cluster >= 0 && !p.ground && p.xyz.allFinite())
			{
				const Eigen::Vector3d q = p.xyz.cast<double>();
				auto& m = mom[p.cluster];
				m[0] += 1;
				m.segment<3>(1) += q;
				m[4] += q.x() * q.x(), m[5] += q.x() * q.y(),
				    m[6] += q.x() * q.z();
				m[7] += q.y() * q.y(), m[8] += q.y() * q.z(),
				    m[9] += q.z() * q.z();
			}
		edge_ok.assign(mom.size(), 2);  // 2: not computed yet
	}
	// Linearity of a cluster, computed on first use (only clusters with an
	// edge candidate need it).
	auto edgeAllowed = [&](const FeatureInputPoint& p)
	{
		if (o.edge_min_linearity <= 0) return true;
		if (p.cluster < 0) return false;
		uint8_t& ok = edge_ok[p.cluster];
		if (ok == 2)
		{
			const auto& m = mom[p.cluster];
			ok = 0;
			if (m[0] >= 3)
			{
				const Eigen::Vector3d mu = m.segment<3>(1) / m[0];
				Eigen::Matrix3d C;
				C << m[4], m[5], m[6], m[5], m[7], m[8], m[6], m[8], m[9];
				C = C / m[0] - mu * mu.transpose();
				const Eigen::Vector3d ev = eigenvalues3(C);  // ascending
				const double l1 = std::sqrt(std::max(0.0, ev[2])),
				             l2 = std::sqrt(std::max(0.0, ev[1]));
				ok = l1 > 0 && (l1 - l2) / l1 >= o.edge_min_linearity;
			}
		}
		return ok == 1;
	};

	const int w = o.half_window;
	std::vector<uint8_t> taken(pts.size(), 0);
	// One ring at a time, gathered into contiguous arrays.
	struct RingPoint
	{
		Eigen::Vector3f xyz;
		float range;
		int32_t cluster;
		int32_t column;
		bool ground;
	};
	std::vector<RingPoint> R;
	std::vector<int> edge_order, planar_order;
	std::vector<float> planar_rank;
	for (int ring = 0; ring <= max_ring; ring++)
	{
		const uint32_t* line = line_of.data() + ring_start[ring];
		const int n = static_cast<int>(ring_start[ring + 1] - ring_start[ring]);
		R.resize(n);
		for (int k = 0; k < n; k++)
		{
			const auto& p = pts[line[k]];
			R[k] = {p.xyz, p.xyz.norm(), p.cluster, p.column, p.ground};
		}
		planar_rank.assign(n, -1.f);
		// Smoothness of clustered points from same-cluster neighbours only.
		for (int k = 0; k < n; k++)
		{
			const auto& pi = R[k];
			if (pi.ground || pi.cluster < 0) continue;
			// Symmetric window: as many same-cluster neighbours on each side
			// (a one-sided window on a flat wall is not flat).
			int left = 0, right = 0;
			while (left < w && k - left - 1 >= 0 &&
			       R[k - left - 1].cluster == pi.cluster)
				left++;
			while (right < w && k + right + 1 < n &&
			       R[k + right + 1].cluster == pi.cluster)
				right++;
			const int m = std::min(left, right);
			float smooth = -1.f;
			if (m >= std::max(2, w / 2))
			{
				Eigen::Vector3f diff = Eigen::Vector3f::Zero();
				for (int d = 1; d <= m; d++)
					diff += R[k - d].xyz + R[k + d].xyz - 2 * pi.xyz;
				smooth = diff.norm() / (2 * m * std::max(pi.range, 1e-3f));
			}
			// Foreground silhouette: an adjacent firing hits another cluster
			// (or the ground) clearly behind this point.
			for (int d : {-1, 1})
			{
				const int j = k + d;
				if (j < 0 || j >= n) continue;
				const auto& pj = R[j];
				if (pj.column - pi.column != d) continue;  // a gap: no evidence
				if (pj.cluster != pi.cluster &&
				    pj.range - pi.range > o.silhouette_gap_m)
					smooth = std::max<float>(
					    smooth, 1.0f + static_cast<float>(o.edge_threshold));
			}
			out.smoothness[line[k]] = smooth;
			// The planar rank: the same window's curvature about the midpoint
			// of the two nearest neighbours instead of the point itself, so
			// that the order does not depend on the point's own range noise.
			// The point's own smoothness still has to pass the threshold
			// (far above the noise on a stem): without it a lone outlier in
			// a flat window was taken (handheld seed 1, odometry only: one
			// stretch lost 4 cm, and the run's scale went from -0.039 to
			// -0.065 %).
			float planar = smooth;
			if (o.planar_from_neighbours && smooth >= 0 &&
			    smooth < o.planar_threshold && m >= 2)
			{
				const Eigen::Vector3f mid =
				    0.5f * (R[k - 1].xyz + R[k + 1].xyz);
				Eigen::Vector3f d2 = Eigen::Vector3f::Zero();
				for (int d = 2; d <= m; d++)
					d2 += R[k - d].xyz + R[k + d].xyz - 2 * mid;
				planar = d2.norm() / (2 * (m - 1) * std::max(pi.range, 1e-3f));
			}
			planar_rank[k] = planar;
		}
		// Per sector: the sharpest edges and the flattest planar points,
		// with neighbours of a chosen point suppressed (LOAM). Only the
		// candidates beyond each threshold are sorted (ties by position).
		for (int sct = 0; sct < o.sectors_per_ring; sct++)
		{
			const int b = n * sct / o.sectors_per_ring;
			const int e = n * (sct + 1) / o.sectors_per_ring;
			edge_order.clear();
			planar_order.clear();
			for (int k = b; k < e; k++)
			{
				const float sm = out.smoothness[line[k]];
				if (sm > o.edge_threshold)
					edge_order.push_back(k);
				else if (sm >= 0 && sm < o.planar_threshold &&
				         planar_rank[k] < o.planar_threshold)
					planar_order.push_back(k);
			}
			// Ties (every silhouette scores the same) are broken by a hash
			// of the point, not by position: by position a sector's quota
			// went to the silhouettes at its start, the first stems in
			// firing order, and left the others unused.
			std::sort(edge_order.begin(), edge_order.end(),
			          [&](int a, int c)
			          {
				          const float sa = out.smoothness[line[a]],
				                      sc = out.smoothness[line[c]];
				          if (sa != sc) return sa > sc;
				          const uint32_t ha = scatterHash(line[a]),
				                         hc = scatterHash(line[c]);
				          return ha < hc || (ha == hc && a < c);
			          });
			std::sort(planar_order.begin(), planar_order.end(),
			          [&](int a, int c)
			          {
				          const float sa = planar_rank[a], sc = planar_rank[c];
				          return sa < sc || (sa == sc && a < c);
			          });
			auto suppress = [&](int k)
			{
				for (int d = -w; d <= w; d++)
					if (k + d >= 0 && k + d < n) taken[line[k + d]] = 1;
			};
			int ne = 0;
			for (int k : edge_order)
			{
				if (ne >= o.max_edges_per_sector) break;
				if (taken[line[k]] || !edgeAllowed(pts[line[k]])) continue;
				out.edges.push_back(line[k]);
				suppress(k);
				ne++;
			}
			int np = 0;
			for (int k : planar_order)
			{
				if (np >= o.max_planar_per_sector) break;
				if (taken[line[k]]) continue;
				out.planar.push_back(line[k]);
				suppress(k);
				np++;
			}
		}
		// Ground: decimated along the ring.
		int g = 0;
		for (int k = 0; k < n; k++)
			if (R[k].ground && (g++ % o.ground_decimation) == 0)
				out.planar.push_back(line[k]);
	}
	return out;
}

}  // namespace forest_slam::features
