#include <forest_slam/core/config.h>
#include <forest_slam/ground/ground_lattice.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

namespace forest_slam::ground
{
void GroundOptions::loadFromConfigFile(
	const mrpt::config::CConfigFileBase& c, const std::string& s)
{
	FS_LOAD(c, s, node_spacing_m);
	FS_LOAD(c, s, radius_m);
	FS_LOAD(c, s, ground_threshold_m);
	FS_LOAD(c, s, lowest_band_m);
	FS_LOAD(c, s, max_slope_deg);
	FS_LOAD(c, s, max_step_m);
	FS_LOAD(c, s, min_points_per_node);
	FS_LOAD(c, s, prior_variance_growth_m2);
	FS_LOAD(c, s, measurement_variance_floor_m2);
	const std::string where = core::configOrigin(c) + ": [" + s + "] ";
	if (!(node_spacing_m > 0.05 && node_spacing_m < 20))
		throw core::ConfigError(where + "node_spacing_m must be in (0.05, 20)");
	if (!(radius_m > node_spacing_m))
		throw core::ConfigError(where + "radius_m must exceed node_spacing_m");
	if (!(ground_threshold_m > 0) || !(lowest_band_m > 0) || !(max_step_m >= 0))
		throw core::ConfigError(
			where + "ground_threshold_m, lowest_band_m must be > 0, max_step_m >= 0");
	if (!(max_slope_deg > 0 && max_slope_deg < 80))
		throw core::ConfigError(where + "max_slope_deg must be in (0, 80)");
	if (min_points_per_node < 1)
		throw core::ConfigError(where + "min_points_per_node must be >= 1");
}

void GroundOptions::saveToConfigFile(
	mrpt::config::CConfigFileBase& c, const std::string& s) const
{
	c.write(s, "node_spacing_m", node_spacing_m);
	c.write(s, "radius_m", radius_m);
	c.write(s, "ground_threshold_m", ground_threshold_m);
	c.write(s, "lowest_band_m", lowest_band_m);
	c.write(s, "max_slope_deg", max_slope_deg);
	c.write(s, "max_step_m", max_step_m);
	c.write(s, "min_points_per_node", min_points_per_node);
	c.write(s, "prior_variance_growth_m2", prior_variance_growth_m2);
	c.write(s, "measurement_variance_floor_m2", measurement_variance_floor_m2);
}

GroundLattice::GroundLattice(const GroundOptions& opts) : opts_(opts) {}

NodeKey GroundLattice::keyOf(double x, double y) const
{
	return {static_cast<int32_t>(std::lround(x / opts_.node_spacing_m)),
			static_cast<int32_t>(std::lround(y / opts_.node_spacing_m))};
}

namespace
{
struct Cell
{
	std::vector<uint32_t> idx;	// points of the cell
	float z_min = std::numeric_limits<float>::max();
	double level = 0;  // median height of the lowest band
	bool accepted = false;
};
}  // namespace

std::vector<uint8_t> GroundLattice::labelScan(
	const std::vector<Eigen::Vector3f>& pts, const Eigen::Vector3d& sensor)
{
	const double s = opts_.node_spacing_m;
	const double r2 = opts_.radius_m * opts_.radius_m;
	std::vector<uint8_t> labels(pts.size(), 0);

	// 1. Nearest node of every point.
	std::unordered_map<NodeKey, Cell, NodeKeyHash> cells;
	cells.reserve(pts.size() / 8 + 16);
	for (uint32_t i = 0; i < pts.size(); i++)
	{
		const auto& p = pts[i];
		if (!p.allFinite()) continue;
		const double dx = p.x() - sensor.x(), dy = p.y() - sensor.y();
		if (dx * dx + dy * dy > r2) continue;
		auto& c = cells[keyOf(p.x(), p.y())];
		c.idx.push_back(i);
		c.z_min = std::min(c.z_min, p.z());
	}

	// 2. Level of each cell: median of its lowest band (robust to a single
	// low outlier and to grass).
	std::vector<float> band;
	for (auto& [key, c] : cells)
	{
		band.clear();
		for (auto i : c.idx)
			if (pts[i].z() <= c.z_min + opts_.lowest_band_m) band.push_back(pts[i].z());
		std::nth_element(band.begin(), band.begin() + band.size() / 2, band.end());
		c.level = band[band.size() / 2];
	}

	// 3. Accept a cell's level as ground only if it is consistent with its
	// surroundings: a plane fitted to the levels of the cells around it
	// (trimmed from above, since shrubs and stems only ever raise a level)
	// must predict it within max_step, and it must not sit far above a
	// confident prior. Shrub tops and stem bases fail where the true ground
	// around them is visible or was seen before.
	const double tan_slope = std::tan(opts_.max_slope_deg * M_PI / 180.0);
	const int reach = 3;
	struct Level
	{
		double dx, dy, z;
		bool used;
	};
	std::vector<Level> around;
	for (auto& [key, c] : cells)
	{
		if (static_cast<int>(c.idx.size()) < opts_.min_points_per_node) continue;
		around.clear();
		for (int di = -reach; di <= reach; di++)
			for (int dj = -reach; dj <= reach; dj++)
			{
				if (!di && !dj) continue;
				const auto it = cells.find({key.i + di, key.j + dj});
				if (it == cells.end() ||
					static_cast<int>(it->second.idx.size()) < opts_.min_points_per_node)
					continue;
				around.push_back({di * s, dj * s, it->second.level, true});
			}
		bool ok = true;
		if (around.size() >= 4)
		{
			Eigen::Vector3d sol(c.level, 0, 0);
			for (int iter = 0; iter < 4; iter++)
			{
				Eigen::Matrix3d A = Eigen::Matrix3d::Identity() * 1e-6;
				Eigen::Vector3d b = Eigen::Vector3d::Zero();
				int n = 0;
				for (const auto& l : around)
					if (l.used)
					{
						const Eigen::Vector3d row(1, l.dx, l.dy);
						A += row * row.transpose();
						b += row * l.z;
						n++;
					}
				if (n < 3) break;
				sol = A.ldlt().solve(b);
				// Trim levels well above the fit (shrubs, stems, walls).
				bool changed = false;
				for (auto& l : around)
				{
					const bool keep = l.z - (sol[0] + sol[1] * l.dx + sol[2] * l.dy) <= opts_.max_step_m;
					changed |= keep != l.used;
					l.used = keep;
				}
				if (!changed) break;
			}
			const double slope = std::hypot(sol[1], sol[2]);
			ok = c.level - sol[0] <= opts_.max_step_m && slope <= tan_slope + 0.2;
		}
		const auto prior = nodes_.find(key);
		if (ok && prior != nodes_.end() && prior->second.var_h < 0.05)
		{
			const double sigma = std::sqrt(prior->second.var_h);
			ok = c.level - prior->second.h <= opts_.max_step_m + 3 * sigma;
		}
		c.accepted = ok;
	}

	// 4. Local plane per accepted node from the lowest-band points of the
	// accepted cells around it, fused with the node's prior (Kalman-style).
	for (auto& [key, c] : cells)
	{
		auto& node = nodes_[key];
		node.var_h += opts_.prior_variance_growth_m2;
		if (!c.accepted) continue;
		const double xc = key.i * s, yc = key.j * s;
		Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
		Eigen::Vector3d b = Eigen::Vector3d::Zero();
		int n = 0;
		for (int di = -1; di <= 1; di++)
			for (int dj = -1; dj <= 1; dj++)
			{
				const auto it = cells.find({key.i + di, key.j + dj});
				if (it == cells.end() || !it->second.accepted) continue;
				for (auto i : it->second.idx)
				{
					const auto& p = pts[i];
					if (p.z() > it->second.level + opts_.lowest_band_m) continue;
					const Eigen::Vector3d row(1, p.x() - xc, p.y() - yc);
					A += row * row.transpose();
					b += row * p.z();
					n++;
				}
			}
		if (n < opts_.min_points_per_node) continue;
		Eigen::Vector3d sol;
		bool plane = A.determinant() > 1e-6 * n * n;
		if (plane)
		{
			sol = A.ldlt().solve(b);
			const double slope = std::hypot(sol[1], sol[2]);
			if (!sol.allFinite() || slope > tan_slope) plane = false;
		}
		if (!plane) sol = Eigen::Vector3d(c.level, node.sx, node.sy);
		// Residual spread of the measurement.
		double ss = 0;
		for (auto i : c.idx)
		{
			const auto& p = pts[i];
			if (p.z() > c.level + opts_.lowest_band_m) continue;
			const double e = p.z() - (sol[0] + sol[1] * (p.x() - xc) + sol[2] * (p.y() - yc));
			ss += e * e;
		}
		const double var_m =
			std::max(opts_.measurement_variance_floor_m2, ss / std::max(1, n));
		const double w = node.var_h / (node.var_h + var_m);
		node.h += w * (sol[0] - node.h);
		node.sx += w * (sol[1] - node.sx);
		node.sy += w * (sol[2] - node.sy);
		node.var_h = node.var_h * var_m / (node.var_h + var_m);
		node.observations++;
	}

	// 5. Labels: height above the node's plane.
	for (auto& [key, c] : cells)
	{
		const auto it = nodes_.find(key);
		if (it == nodes_.end() || it->second.observations == 0) continue;
		const auto& node = it->second;
		const double xc = key.i * s, yc = key.j * s;
		for (auto i : c.idx)
		{
			const auto& p = pts[i];
			const double dz = p.z() - (node.h + node.sx * (p.x() - xc) + node.sy * (p.y() - yc));
			labels[i] = dz < opts_.ground_threshold_m ? 1 : 0;
		}
	}
	return labels;
}

bool GroundLattice::heightAt(double x, double y, double& z) const
{
	const double s = opts_.node_spacing_m;
	const double fx = x / s, fy = y / s;
	const int i0 = static_cast<int>(std::floor(fx)), j0 = static_cast<int>(std::floor(fy));
	double wsum = 0, zsum = 0;
	for (int di = 0; di <= 1; di++)
		for (int dj = 0; dj <= 1; dj++)
		{
			const auto it = nodes_.find({i0 + di, j0 + dj});
			if (it == nodes_.end() || it->second.observations == 0) continue;
			const double w = (di ? fx - i0 : 1 - (fx - i0)) * (dj ? fy - j0 : 1 - (fy - j0));
			const auto& n = it->second;
			// Each node predicts with its own plane; blend bilinearly.
			const double zn = n.h + n.sx * (x - (i0 + di) * s) + n.sy * (y - (j0 + dj) * s);
			zsum += (w + 1e-9) * zn;
			wsum += w + 1e-9;
		}
	if (wsum <= 0) return false;
	z = zsum / wsum;
	return true;
}

}  // namespace forest_slam::ground
