#include <forest_slam/core/atomic_file.h>
#include <forest_slam/ground/ground_lattice.h>
#include <forest_slam/outputs/classification.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <unordered_map>

namespace forest_slam::outputs
{
namespace
{
void bounds(const std::vector<DensePoint>& pts, Eigen::Vector2d& lo,
            Eigen::Vector2d& hi)
{
	lo.setConstant(std::numeric_limits<double>::infinity());
	hi = -lo;
	for (const auto& p : pts)
	{
		lo = lo.cwiseMin(p.xyz.head<2>().cast<double>());
		hi = hi.cwiseMax(p.xyz.head<2>().cast<double>());
	}
}
}  // namespace

trees::TerrainModel terrainForCloud(const std::vector<DensePoint>& pts,
                                    const ground::GroundLattice* lattice,
                                    const trees::TreeOptions& tree_opts)
{
	if (pts.empty())
		throw std::invalid_argument("terrainForCloud: the dense map is empty");
	if (lattice && !lattice->nodes().empty())
	{
		Eigen::Vector2d lo, hi;
		bounds(pts, lo, hi);
		const double cell = lattice->options().node_spacing_m;
		const int nx =
		    static_cast<int>(std::ceil((hi.x() - lo.x()) / cell)) + 1;
		const int ny =
		    static_cast<int>(std::ceil((hi.y() - lo.y()) / cell)) + 1;
		std::vector<double> h(size_t(nx) * ny,
		                      std::numeric_limits<double>::quiet_NaN());
		size_t known = 0;
		for (int iy = 0; iy < ny; iy++)
			for (int ix = 0; ix < nx; ix++)
			{
				double z;
				if (lattice->heightAt(lo.x() + ix * cell, lo.y() + iy * cell,
				                      z))
				{
					h[ix + size_t(nx) * iy] = z;
					known++;
				}
			}
		if (known > 0)
			return trees::TerrainModel(lo.x(), lo.y(), cell, nx, ny,
			                           std::move(h));
	}
	std::vector<Eigen::Vector3d> xyz(pts.size());
	for (size_t i = 0; i < pts.size(); i++) xyz[i] = pts[i].xyz.cast<double>();
	return trees::buildDtm(xyz, tree_opts);
}

std::vector<uint8_t> classifyPoints(const std::vector<DensePoint>& pts,
                                    const trees::TerrainModel& terrain,
                                    const std::vector<map::TreeRecord>& trees,
                                    const OutputOptions& o)
{
	// Stems indexed on a 1 m grid by every cell their circle + margin touches.
	constexpr double kCell = 1.0;
	const auto cellKey = [](int64_t i, int64_t j)
	{
		return (static_cast<uint64_t>(i + (1 << 30)) << 32) |
		       static_cast<uint64_t>(j + (1 << 30));
	};
	std::unordered_map<uint64_t, std::vector<size_t>> stem_cells;
	for (size_t t = 0; t < trees.size(); t++)
	{
		const double r = trees[t].dbh_m / 2 + o.stem_margin_m;
		for (int64_t i = std::floor((trees[t].x - r) / kCell);
		     i <= std::floor((trees[t].x + r) / kCell); i++)
			for (int64_t j = std::floor((trees[t].y - r) / kCell);
			     j <= std::floor((trees[t].y + r) / kCell); j++)
				stem_cells[cellKey(i, j)].push_back(t);
	}

	std::vector<uint8_t> cls(pts.size(), kUnclassified);
	if (terrain.empty()) return cls;
	const double g = o.ground_threshold_m;
	for (size_t k = 0; k < pts.size(); k++)
	{
		const Eigen::Vector3d p = pts[k].xyz.cast<double>();
		const double h = terrain.heightAboveGround(p);
		uint8_t c;
		if (h < -3 * g)
			c = kLowNoise;
		else if (h <= g)
			c = kGround;
		else if (h <= o.low_vegetation_max_m)
			c = kLowVegetation;
		else if (h <= o.medium_vegetation_max_m)
			c = kMediumVegetation;
		else
			c = kHighVegetation;
		if (h > g && h <= o.stem_max_height_m && !stem_cells.empty())
		{
			const auto it = stem_cells.find(
			    cellKey(static_cast<int64_t>(std::floor(p.x() / kCell)),
			            static_cast<int64_t>(std::floor(p.y() / kCell))));
			if (it != stem_cells.end())
				for (const size_t t : it->second)
				{
					const double r = trees[t].dbh_m / 2 + o.stem_margin_m;
					if (std::hypot(p.x() - trees[t].x, p.y() - trees[t].y) <= r)
					{
						c = static_cast<uint8_t>(o.stem_class);
						break;
					}
				}
		}
		cls[k] = c;
	}
	return cls;
}

size_t ElevationGrid::cellsWithData() const
{
	return std::count_if(z.begin(), z.end(),
	                     [](double v) { return std::isfinite(v); });
}

ElevationGrid groundGrid(
    const std::vector<DensePoint>& pts, const std::vector<uint8_t>& classes,
    double cell_m,
    const std::function<Eigen::Vector3d(const Eigen::Vector3d&)>& to_output)
{
	std::vector<Eigen::Vector3d> ground;
	for (size_t k = 0; k < pts.size(); k++)
		if (classes[k] == kGround)
			ground.push_back(to_output(pts[k].xyz.cast<double>()));
	ElevationGrid g;
	g.cell_m = cell_m;
	if (ground.empty()) return g;
	Eigen::Vector2d lo = ground[0].head<2>(), hi = lo;
	for (const auto& p : ground)
	{
		lo = lo.cwiseMin(p.head<2>());
		hi = hi.cwiseMax(p.head<2>());
	}
	// Corner on a multiple of the cell so grids of the same area line up.
	g.x0 = std::floor(lo.x() / cell_m) * cell_m;
	g.y0 = std::floor(lo.y() / cell_m) * cell_m;
	g.nx = static_cast<int>(std::floor((hi.x() - g.x0) / cell_m)) + 1;
	g.ny = static_cast<int>(std::floor((hi.y() - g.y0) / cell_m)) + 1;
	std::vector<double> sum(size_t(g.nx) * g.ny, 0.0);
	std::vector<uint32_t> n(sum.size(), 0);
	for (const auto& p : ground)
	{
		const int ix =
		    std::min(g.nx - 1, static_cast<int>((p.x() - g.x0) / cell_m));
		const int iy =
		    std::min(g.ny - 1, static_cast<int>((p.y() - g.y0) / cell_m));
		sum[ix + size_t(g.nx) * iy] += p.z();
		n[ix + size_t(g.nx) * iy]++;
	}
	g.z.assign(sum.size(), std::numeric_limits<double>::quiet_NaN());
	for (size_t i = 0; i < sum.size(); i++)
		if (n[i] > 0) g.z[i] = sum[i] / n[i];
	return g;
}

void writeEsriAscii(const std::string& path, const ElevationGrid& g)
{
	if (g.nx <= 0 || g.ny <= 0)
		throw std::runtime_error("'" + path + "': the DTM has no ground cell");
	core::writeFileAtomically(
	    path,
	    [&](std::ostream& os)
	    {
		    char line[128];
		    std::snprintf(line, sizeof(line),
		                  "ncols %d\nnrows %d\nxllcorner %.3f\nyllcorner %.3f\n"
		                  "cellsize %.6g\nNODATA_value -9999\n",
		                  g.nx, g.ny, g.x0, g.y0, g.cell_m);
		    os << line;
		    // Rows from north to south (ESRI convention).
		    for (int iy = g.ny - 1; iy >= 0; iy--)
		    {
			    for (int ix = 0; ix < g.nx; ix++)
			    {
				    const double v = g.at(ix, iy);
				    if (std::isfinite(v))
					    std::snprintf(line, sizeof(line), "%.3f", v);
				    else
					    std::snprintf(line, sizeof(line), "-9999");
				    os << (ix ? " " : "") << line;
			    }
			    os << "\n";
		    }
	    });
}

}  // namespace forest_slam::outputs
