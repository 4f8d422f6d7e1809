#include <forest_slam/trees/terrain_model.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace forest_slam::trees
{
namespace
{
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/** Fills NaN cells with the mean of their known 8-neighbours, growing
 * outwards until the grid is full. */
void fillHoles(std::vector<double>& h, int nx, int ny)
{
	for (;;)
	{
		bool any_missing = false, changed = false;
		auto next = h;
		for (int iy = 0; iy < ny; iy++)
			for (int ix = 0; ix < nx; ix++)
			{
				if (!std::isnan(h[ix + nx * iy])) continue;
				any_missing = true;
				double sum = 0;
				int n = 0;
				for (int dy = -1; dy <= 1; dy++)
					for (int dx = -1; dx <= 1; dx++)
					{
						const int jx = ix + dx, jy = iy + dy;
						if (jx < 0 || jy < 0 || jx >= nx || jy >= ny) continue;
						const double v = h[jx + nx * jy];
						if (!std::isnan(v)) sum += v, n++;
					}
				if (n)
				{
					next[ix + nx * iy] = sum / n;
					changed = true;
				}
			}
		h.swap(next);
		if (!any_missing || !changed) return;
	}
}
}  // namespace

TerrainModel::TerrainModel(double x0, double y0, double cell_m, int nx, int ny,
                           std::vector<double> heights)
    : x0_(x0),
      y0_(y0),
      cell_m_(cell_m),
      nx_(nx),
      ny_(ny),
      h_(std::move(heights))
{
	if (nx <= 0 || ny <= 0 || cell_m <= 0 || h_.size() != size_t(nx) * ny)
		throw std::invalid_argument(
		    "TerrainModel: grid size does not match heights");
	if (std::all_of(h_.begin(), h_.end(),
	                [](double v) { return std::isnan(v); }))
		throw std::invalid_argument("TerrainModel: no known cell");
	fillHoles(h_, nx_, ny_);
}

double TerrainModel::heightAt(double x, double y) const
{
	if (h_.empty())
		throw std::logic_error("TerrainModel::heightAt on an empty model");
	const double fx = std::clamp((x - x0_) / cell_m_, 0.0, double(nx_ - 1));
	const double fy = std::clamp((y - y0_) / cell_m_, 0.0, double(ny_ - 1));
	const int ix = std::min(int(fx), std::max(nx_ - 2, 0));
	const int iy = std::min(int(fy), std::max(ny_ - 2, 0));
	const int jx = std::min(ix + 1, nx_ - 1), jy = std::min(iy + 1, ny_ - 1);
	const double ax = fx - ix, ay = fy - iy;
	return (1 - ay) * ((1 - ax) * cell(ix, iy) + ax * cell(jx, iy)) +
	       ay * ((1 - ax) * cell(ix, jy) + ax * cell(jx, jy));
}

TerrainModel buildDtm(const std::vector<Eigen::Vector3d>& pts,
                      const TreeOptions& o)
{
	if (pts.empty()) throw std::invalid_argument("buildDtm: empty cloud");
	double xmin = pts[0].x(), ymin = pts[0].y(), xmax = xmin, ymax = ymin;
	for (const auto& p : pts)
	{
		xmin = std::min(xmin, p.x()), xmax = std::max(xmax, p.x());
		ymin = std::min(ymin, p.y()), ymax = std::max(ymax, p.y());
	}
	const double c = o.dtm_cell_m;
	const int nx = int(std::floor((xmax - xmin) / c)) + 1;
	const int ny = int(std::floor((ymax - ymin) / c)) + 1;
	if (double(nx) * ny > 5e7)
		throw std::invalid_argument("buildDtm: cloud too large for dtm_cell_m");
	std::vector<double> low(size_t(nx) * ny, kNaN);
	std::vector<Eigen::Vector3d> lowest(low.size());
	for (const auto& p : pts)
	{
		const int ix = int((p.x() - xmin) / c), iy = int((p.y() - ymin) / c);
		double& v = low[ix + nx * iy];
		if (std::isnan(v) || p.z() < v) v = p.z(), lowest[ix + nx * iy] = p;
	}
	// Ground never rises from a lower cell more steeply than
	// dtm_max_slope_deg: a cell above that bound is not ground. Where the
	// ground is hidden (stems and shrubs seen from 15-25 m), the clutter's
	// lowest points are the majority of the median's window below, which
	// then keeps them and drops the few cells that did see the ground (the
	// 58-minute run: a DTM 3.4 m high under two stems, whose slices then
	// lay 3.9-6.5 m up; doc/trees.md "Trees beyond 15 m of the path"). The
	// bound is the grid's lower envelope under that slope, in two chamfer
	// passes (8 neighbours: within 8 % of the Euclidean distance).
	if (o.dtm_max_slope_deg > 0)
	{
		const double rise = std::tan(o.dtm_max_slope_deg * M_PI / 180) * c;
		const double diag = rise * std::sqrt(2.0);
		const double inf = std::numeric_limits<double>::infinity();
		std::vector<double> env(low.size());
		for (size_t i = 0; i < low.size(); i++)
			env[i] = std::isnan(low[i]) ? inf : low[i];
		auto relax = [&](int ix, int iy, int dx, int dy, double step)
		{
			const int jx = ix + dx, jy = iy + dy;
			if (jx < 0 || jy < 0 || jx >= nx || jy >= ny) return;
			double& e = env[ix + nx * iy];
			e = std::min(e, env[jx + nx * jy] + step);
		};
		for (int iy = 0; iy < ny; iy++)
			for (int ix = 0; ix < nx; ix++)
			{
				relax(ix, iy, -1, 0, rise), relax(ix, iy, 0, -1, rise);
				relax(ix, iy, -1, -1, diag), relax(ix, iy, 1, -1, diag);
			}
		for (int iy = ny - 1; iy >= 0; iy--)
			for (int ix = nx - 1; ix >= 0; ix--)
			{
				relax(ix, iy, 1, 0, rise), relax(ix, iy, 0, 1, rise);
				relax(ix, iy, 1, 1, diag), relax(ix, iy, -1, 1, diag);
			}
		for (size_t i = 0; i < low.size(); i++)
			if (low[i] > env[i] + o.dtm_max_step_m) low[i] = kNaN;
	}
	// Median filter of the neighbourhood: a cell is ground if it agrees with
	// the median of its window. On a plane of any slope the median of a
	// symmetric window equals the centre value, so slopes pass unchanged.
	const int w = std::max(1, o.dtm_window_cells);
	std::vector<double> filtered(low.size(), kNaN);
	std::vector<double> win;
	for (int iy = 0; iy < ny; iy++)
		for (int ix = 0; ix < nx; ix++)
		{
			const double v = low[ix + nx * iy];
			if (std::isnan(v)) continue;
			win.clear();
			for (int dy = -w; dy <= w; dy++)
				for (int dx = -w; dx <= w; dx++)
				{
					const int jx = ix + dx, jy = iy + dy;
					if (jx < 0 || jy < 0 || jx >= nx || jy >= ny) continue;
					const double u = low[jx + nx * jy];
					if (!std::isnan(u)) win.push_back(u);
				}
			std::nth_element(win.begin(), win.begin() + win.size() / 2,
			                 win.end());
			const double med = win[win.size() / 2];
			if (std::abs(v - med) <= o.dtm_max_step_m)
				filtered[ix + nx * iy] = v;
		}
	// The lowest point of a sloped cell lies on its downhill edge; a plane
	// through the accepted lowest points of the 3x3 window, evaluated at the
	// cell centre, removes that bias (slope * cell / 2).
	std::vector<double> centred(filtered.size(), kNaN);
	for (int iy = 0; iy < ny; iy++)
		for (int ix = 0; ix < nx; ix++)
		{
			if (std::isnan(filtered[ix + nx * iy])) continue;
			const double cx = xmin + (ix + 0.5) * c, cy = ymin + (iy + 0.5) * c;
			Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
			Eigen::Vector3d b = Eigen::Vector3d::Zero();
			int n = 0;
			for (int dy = -1; dy <= 1; dy++)
				for (int dx = -1; dx <= 1; dx++)
				{
					const int jx = ix + dx, jy = iy + dy;
					if (jx < 0 || jy < 0 || jx >= nx || jy >= ny) continue;
					if (std::isnan(filtered[jx + nx * jy])) continue;
					const auto& q = lowest[jx + nx * jy];
					const Eigen::Vector3d r(q.x() - cx, q.y() - cy, 1.0);
					A += r * r.transpose();
					b += r * q.z();
					n++;
				}
			const Eigen::Vector3d sol = A.ldlt().solve(b);
			const bool ok =
			    n >= 4 && std::abs(A.determinant()) > 1e-6 * std::pow(c, 4) &&
			    sol.allFinite() &&
			    std::abs(sol.z() - filtered[ix + nx * iy]) <= o.dtm_max_step_m;
			centred[ix + nx * iy] = ok ? sol.z() : filtered[ix + nx * iy];
		}
	filtered.swap(centred);
	// Cells on the rejected side keep no value: fall back to raw minima only
	// if the filter rejected everything (a single-cell cloud).
	if (std::all_of(filtered.begin(), filtered.end(),
	                [](double v) { return std::isnan(v); }))
		filtered = low;
	return TerrainModel(xmin + 0.5 * c, ymin + 0.5 * c, c, nx, ny,
	                    std::move(filtered));
}

}  // namespace forest_slam::trees
