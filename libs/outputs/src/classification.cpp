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

trees::TerrainModel terrainForCloud(const DenseMap& dense,
                                    const ground::GroundLattice* lattice,
                                    const trees::TreeOptions& tree_opts)
{
	if (dense.size() == 0)
		throw std::invalid_argument("terrainForCloud: the dense map is empty");
	if (lattice && !lattice->nodes().empty())
	{
		// Only the bounds matter here: a point per tile corner does.
		std::vector<DensePoint> corners;
		dense.forEachTile(
		    [&](const std::vector<DensePoint>& pts)
		    {
			    Eigen::Vector2d lo, hi;
			    bounds(pts, lo, hi);
			    DensePoint a, b;
			    a.xyz << float(lo.x()), float(lo.y()), 0.f;
			    b.xyz << float(hi.x()), float(hi.y()), 0.f;
			    corners.push_back(a);
			    corners.push_back(b);
		    });
		return terrainForCloud(corners, lattice, tree_opts);
	}
	return terrainForCloud(dense.points(), nullptr, tree_opts);
}

namespace
{
uint64_t stemCellKey(int64_t i, int64_t j)
{
	return (static_cast<uint64_t>(i + (1 << 30)) << 32) |
	       static_cast<uint64_t>(j + (1 << 30));
}
constexpr double kStemCell = 1.0;
}  // namespace

PointClassifier::PointClassifier(const trees::TerrainModel& terrain,
                                 const std::vector<map::TreeRecord>& trees,
                                 const OutputOptions& o)
    : terrain_(terrain), trees_(trees), o_(o)
{
	for (size_t t = 0; t < trees.size(); t++)
	{
		const double r = trees[t].dbh_m / 2 + o.stem_margin_m;
		for (int64_t i = std::floor((trees[t].x - r) / kStemCell);
		     i <= std::floor((trees[t].x + r) / kStemCell); i++)
			for (int64_t j = std::floor((trees[t].y - r) / kStemCell);
			     j <= std::floor((trees[t].y + r) / kStemCell); j++)
				stem_cells_[stemCellKey(i, j)].push_back(t);
	}
}

uint8_t PointClassifier::classify(const Eigen::Vector3d& p) const
{
	if (terrain_.empty()) return kUnclassified;
	const double g = o_.ground_threshold_m;
	const double h = terrain_.heightAboveGround(p);
	uint8_t c;
	if (h < -3 * g)
		c = kLowNoise;
	else if (h <= g)
		c = kGround;
	else if (h <= o_.low_vegetation_max_m)
		c = kLowVegetation;
	else if (h <= o_.medium_vegetation_max_m)
		c = kMediumVegetation;
	else
		c = kHighVegetation;
	if (h > g && h <= o_.stem_max_height_m && !stem_cells_.empty())
	{
		const auto it = stem_cells_.find(
		    stemCellKey(static_cast<int64_t>(std::floor(p.x() / kStemCell)),
		                static_cast<int64_t>(std::floor(p.y() / kStemCell))));
		if (it != stem_cells_.end())
			for (const size_t t : it->second)
			{
				const double r = trees_[t].dbh_m / 2 + o_.stem_margin_m;
				if (std::hypot(p.x() - trees_[t].x, p.y() - trees_[t].y) <= r)
				{
					c = static_cast<uint8_t>(o_.stem_class);
					break;
				}
			}
	}
	return c;
}

std::vector<uint8_t> classifyPoints(const std::vector<DensePoint>& pts,
                                    const trees::TerrainModel& terrain,
                                    const std::vector<map::TreeRecord>& trees,
                                    const OutputOptions& o)
{
	const PointClassifier c(terrain, trees, o);
	std::vector<uint8_t> cls(pts.size(), kUnclassified);
	for (size_t k = 0; k < pts.size(); k++)
		cls[k] = c.classify(pts[k].xyz.cast<double>());
	return cls;
}

size_t ElevationGrid::cellsWithData() const
{
	return std::count_if(z.begin(), z.end(),
	                     [](double v) { return std::isfinite(v); });
}

void GroundGridBuilder::add(const Eigen::Vector3d& p)
{
	const int64_t ix = static_cast<int64_t>(std::floor(p.x() / cell_m_));
	const int64_t iy = static_cast<int64_t>(std::floor(p.y() / cell_m_));
	if (cells_.empty()) ix_lo_ = ix_hi_ = ix, iy_lo_ = iy_hi_ = iy;
	ix_lo_ = std::min(ix_lo_, ix), ix_hi_ = std::max(ix_hi_, ix);
	iy_lo_ = std::min(iy_lo_, iy), iy_hi_ = std::max(iy_hi_, iy);
	Cell& c = cells_[stemCellKey(ix, iy)];
	c.sum += p.z();
	c.n++;
}

ElevationGrid GroundGridBuilder::grid() const
{
	ElevationGrid g;
	g.cell_m = cell_m_;
	if (cells_.empty()) return g;
	// Corner on a multiple of the cell so grids of the same area line up.
	g.x0 = ix_lo_ * cell_m_;
	g.y0 = iy_lo_ * cell_m_;
	g.nx = static_cast<int>(ix_hi_ - ix_lo_ + 1);
	g.ny = static_cast<int>(iy_hi_ - iy_lo_ + 1);
	g.z.assign(size_t(g.nx) * g.ny, std::numeric_limits<double>::quiet_NaN());
	for (int64_t iy = iy_lo_; iy <= iy_hi_; iy++)
		for (int64_t ix = ix_lo_; ix <= ix_hi_; ix++)
		{
			const auto it = cells_.find(stemCellKey(ix, iy));
			if (it != cells_.end())
				g.z[(ix - ix_lo_) + size_t(g.nx) * (iy - iy_lo_)] =
				    it->second.sum / it->second.n;
		}
	return g;
}

ElevationGrid groundGrid(
    const std::vector<DensePoint>& pts, const std::vector<uint8_t>& classes,
    double cell_m,
    const std::function<Eigen::Vector3d(const Eigen::Vector3d&)>& to_output)
{
	GroundGridBuilder b(cell_m);
	for (size_t k = 0; k < pts.size(); k++)
		if (classes[k] == kGround) b.add(to_output(pts[k].xyz.cast<double>()));
	return b.grid();
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
