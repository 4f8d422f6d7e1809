#include <forest_slam/core/config.h>
#include <forest_slam/features/feature_extractor.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
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
}

Features extractFeatures(const std::vector<FeatureInputPoint>& pts,
                         const FeatureOptions& o)
{
	Features out;
	out.smoothness.assign(pts.size(), -1.f);
	if (pts.empty()) return out;
	int max_ring = 0;
	for (const auto& p : pts) max_ring = std::max<int>(max_ring, p.ring);
	// Ring lines ordered by firing column.
	std::vector<std::vector<uint32_t>> rings(max_ring + 1);
	for (uint32_t i = 0; i < pts.size(); i++)
		if (pts[i].xyz.allFinite()) rings[pts[i].ring].push_back(i);

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
				const Eigen::Vector3d ev =
				    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(
				        C, Eigen::EigenvaluesOnly)
				        .eigenvalues();  // ascending
				const double l1 = std::sqrt(std::max(0.0, ev[2])),
				             l2 = std::sqrt(std::max(0.0, ev[1]));
				ok = l1 > 0 && (l1 - l2) / l1 >= o.edge_min_linearity;
			}
		}
		return ok == 1;
	};

	const int w = o.half_window;
	std::vector<uint8_t> taken(pts.size(), 0);
	for (auto& line : rings)
	{
		std::stable_sort(line.begin(), line.end(),
		                 [&](uint32_t a, uint32_t b)
		                 { return pts[a].column < pts[b].column; });
		const int n = static_cast<int>(line.size());
		// Smoothness of clustered points from same-cluster neighbours only.
		for (int k = 0; k < n; k++)
		{
			const auto& pi = pts[line[k]];
			if (pi.ground || pi.cluster < 0) continue;
			// Symmetric window: as many same-cluster neighbours on each side
			// (a one-sided window on a flat wall is not flat).
			auto sideCount = [&](int dir)
			{
				int m = 0;
				while (m < w)
				{
					const int j = k + dir * (m + 1);
					if (j < 0 || j >= n || pts[line[j]].cluster != pi.cluster)
						break;
					m++;
				}
				return m;
			};
			const int m = std::min(sideCount(-1), sideCount(1));
			float smooth = -1.f;
			if (m >= std::max(2, w / 2))
			{
				Eigen::Vector3f diff = Eigen::Vector3f::Zero();
				for (int d = 1; d <= m; d++)
					diff += pts[line[k - d]].xyz + pts[line[k + d]].xyz -
					        2 * pi.xyz;
				smooth = diff.norm() / (2 * m * std::max(pi.xyz.norm(), 1e-3f));
			}
			// Foreground silhouette: an adjacent firing hits another cluster
			// (or the ground) clearly behind this point.
			const float r = pi.xyz.norm();
			for (int d : {-1, 1})
			{
				const int j = k + d;
				if (j < 0 || j >= n) continue;
				const auto& pj = pts[line[j]];
				if (pj.column - pi.column != d) continue;  // a gap: no evidence
				if (pj.cluster != pi.cluster &&
				    pj.xyz.norm() - r > o.silhouette_gap_m)
					smooth = std::max<float>(
					    smooth, 1.0f + static_cast<float>(o.edge_threshold));
			}
			out.smoothness[line[k]] = smooth;
		}
		// Per sector: the sharpest edges and the flattest planar points,
		// with neighbours of a chosen point suppressed (LOAM).
		for (int sct = 0; sct < o.sectors_per_ring; sct++)
		{
			const int b = n * sct / o.sectors_per_ring;
			const int e = n * (sct + 1) / o.sectors_per_ring;
			std::vector<int> order;
			for (int k = b; k < e; k++)
				if (out.smoothness[line[k]] >= 0) order.push_back(k);
			std::sort(
			    order.begin(), order.end(),
			    [&](int a, int c)
			    { return out.smoothness[line[a]] > out.smoothness[line[c]]; });
			auto suppress = [&](int k)
			{
				for (int d = -w; d <= w; d++)
					if (k + d >= 0 && k + d < n) taken[line[k + d]] = 1;
			};
			int ne = 0;
			for (int k : order)
			{
				if (ne >= o.max_edges_per_sector) break;
				if (out.smoothness[line[k]] <= o.edge_threshold) break;
				if (taken[line[k]] || !edgeAllowed(pts[line[k]])) continue;
				out.edges.push_back(line[k]);
				suppress(k);
				ne++;
			}
			int np = 0;
			for (auto it = order.rbegin(); it != order.rend(); ++it)
			{
				const int k = *it;
				if (np >= o.max_planar_per_sector) break;
				if (out.smoothness[line[k]] >= o.planar_threshold) break;
				if (taken[line[k]]) continue;
				out.planar.push_back(line[k]);
				suppress(k);
				np++;
			}
		}
		// Ground: decimated along the ring.
		int g = 0;
		for (int k = 0; k < n; k++)
			if (pts[line[k]].ground && (g++ % o.ground_decimation) == 0)
				out.planar.push_back(line[k]);
	}
	return out;
}

}  // namespace forest_slam::features
