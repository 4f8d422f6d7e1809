#include <forest_slam/sim/terrain.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace forest_slam::sim
{
GridField::GridField(double x0, double y0, double step, int nx, int ny)
    : x0_(x0),
      y0_(y0),
      step_(step),
      inv_step_(1.0 / step),
      nx_(std::max(nx, 2)),
      ny_(std::max(ny, 2)),
      v_(static_cast<size_t>(nx_) * ny_, 0.0)
{
}

double GridField::value(double x, double y) const
{
	double fx = (x - x0_) * inv_step_, fy = (y - y0_) * inv_step_;
	fx = std::clamp(fx, 0.0, nx_ - 1.0);
	fy = std::clamp(fy, 0.0, ny_ - 1.0);
	const int ix = std::min(static_cast<int>(fx), nx_ - 2);
	const int iy = std::min(static_cast<int>(fy), ny_ - 2);
	const double u = fx - ix, v = fy - iy;
	const double* r0 = &v_[static_cast<size_t>(iy) * nx_ + ix];
	const double* r1 = r0 + nx_;
	return (1 - v) * ((1 - u) * r0[0] + u * r0[1]) +
	       v * ((1 - u) * r1[0] + u * r1[1]);
}

Eigen::Vector2d GridField::gradient(double x, double y) const
{
	double fx = (x - x0_) * inv_step_, fy = (y - y0_) * inv_step_;
	const bool outx = fx < 0 || fx > nx_ - 1, outy = fy < 0 || fy > ny_ - 1;
	fx = std::clamp(fx, 0.0, nx_ - 1.0);
	fy = std::clamp(fy, 0.0, ny_ - 1.0);
	const int ix = std::min(static_cast<int>(fx), nx_ - 2);
	const int iy = std::min(static_cast<int>(fy), ny_ - 2);
	const double u = fx - ix, v = fy - iy;
	const double* r0 = &v_[static_cast<size_t>(iy) * nx_ + ix];
	const double* r1 = r0 + nx_;
	// Clamped outside the grid: the field is constant across the border.
	const double gx =
	    outx ? 0.0
	         : ((1 - v) * (r0[1] - r0[0]) + v * (r1[1] - r1[0])) * inv_step_;
	const double gy =
	    outy ? 0.0
	         : ((1 - u) * (r1[0] - r0[0]) + u * (r1[1] - r0[1])) * inv_step_;
	return {gx, gy};
}

double GridField::minValue() const
{
	return *std::min_element(v_.begin(), v_.end());
}
double GridField::maxValue() const
{
	return *std::max_element(v_.begin(), v_.end());
}

namespace
{
double smoothstep(double e0, double e1, double x)
{
	const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
	return t * t * (3 - 2 * t);
}

/** Max slope [rad] of the bilinear field measured along grid edges and
 * diagonals (what a walker feels), not the Lipschitz bound. */
double maxSlope(const GridField& f)
{
	double best = 0;
	for (int iy = 0; iy + 1 < f.ny(); iy++)
		for (int ix = 0; ix + 1 < f.nx(); ix++)
		{
			const double gx = (f.at(ix + 1, iy) - f.at(ix, iy)) / f.step();
			const double gy = (f.at(ix, iy + 1) - f.at(ix, iy)) / f.step();
			best = std::max(best, std::hypot(gx, gy));
		}
	return std::atan(best);
}
}  // namespace

Terrain::Terrain(const TerrainOptions& o, double xmin, double ymin, double xmax,
                 double ymax, double flat_radius_m, double flat_blend_m,
                 const std::function<double(double, double)>& roughness_factor,
                 Rng& rng)
{
	if (!(xmax > xmin && ymax > ymin))
		throw std::invalid_argument("Terrain: empty world bounds");
	const double step = o.grid_step_m;
	const int nx = static_cast<int>(std::ceil((xmax - xmin) / step)) + 1;
	const int ny = static_cast<int>(std::ceil((ymax - ymin) / step)) + 1;
	smooth_ = GridField(xmin, ymin, step, nx, ny);

	// Hills: random plane waves with wavelengths from feature_size to 4x it,
	// amplitude proportional to wavelength so every band adds similar slope.
	struct Wave
	{
		double kx, ky, amp, phase;
	};
	std::vector<Wave> waves;
	const int n_waves = 24;
	for (int i = 0; i < n_waves; i++)
	{
		const double lambda = o.feature_size_m * std::pow(4.0, rng.uniform());
		const double dir = rng.uniform(0, 2 * M_PI);
		const double k = 2 * M_PI / lambda;
		waves.push_back({k * std::cos(dir), k * std::sin(dir),
		                 lambda * rng.uniform(0.5, 1.0),
		                 rng.uniform(0, 2 * M_PI)});
	}
	auto raw = [&](double x, double y)
	{
		double h = 0;
		for (const auto& w : waves)
			h += w.amp * std::cos(w.kx * x + w.ky * y + w.phase);
		return h;
	};
	for (int iy = 0; iy < smooth_.ny(); iy++)
		for (int ix = 0; ix < smooth_.nx(); ix++)
			smooth_.at(ix, iy) = raw(smooth_.xOf(ix), smooth_.yOf(iy));

	// Level the yard around the start and put the start at height 0.
	const double h0 = raw(0, 0);
	const double blend = std::max(flat_blend_m, 1.0);
	for (int iy = 0; iy < smooth_.ny(); iy++)
		for (int ix = 0; ix < smooth_.nx(); ix++)
		{
			const double r = std::hypot(smooth_.xOf(ix), smooth_.yOf(iy));
			const double w =
			    1.0 - smoothstep(flat_radius_m, flat_radius_m + blend, r);
			double& h = smooth_.at(ix, iy);
			h = (1 - w) * (h - h0);
		}

	// Scale to the requested relief, then down again if any slope (including
	// the yard's blend ring) exceeds the limit.
	const double range0 = smooth_.maxValue() - smooth_.minValue();
	const double slope0 = std::tan(maxSlope(smooth_));
	double scale = range0 > 1e-9 ? o.elevation_range_m / range0 : 0.0;
	const double max_tan = std::tan(o.max_slope_deg * M_PI / 180.0);
	if (slope0 * scale > max_tan && slope0 > 1e-12) scale = max_tan / slope0;
	for (int iy = 0; iy < smooth_.ny(); iy++)
		for (int ix = 0; ix < smooth_.nx(); ix++) smooth_.at(ix, iy) *= scale;
	stats_.elevation_range_m = smooth_.maxValue() - smooth_.minValue();
	stats_.max_slope_deg = maxSlope(smooth_) * 180.0 / M_PI;

	// Forest floor micro relief: white noise smoothed by a 3x3 binomial
	// kernel, scaled to the requested standard deviation.
	const double rs = o.roughness_step_m;
	const int rnx = static_cast<int>(std::ceil((xmax - xmin) / rs)) + 1;
	const int rny = static_cast<int>(std::ceil((ymax - ymin) / rs)) + 1;
	GridField rough(xmin, ymin, rs, rnx, rny);  // local: folded into full_
	if (o.roughness_m > 0)
	{
		GridField white(xmin, ymin, rs, rnx, rny);
		for (int iy = 0; iy < white.ny(); iy++)
			for (int ix = 0; ix < white.nx(); ix++)
				white.at(ix, iy) = rng.normal();
		const double k[3] = {0.25, 0.5, 0.25};
		for (int iy = 0; iy < rough.ny(); iy++)
			for (int ix = 0; ix < rough.nx(); ix++)
			{
				double s = 0;
				for (int dy = -1; dy <= 1; dy++)
					for (int dx = -1; dx <= 1; dx++)
					{
						const int jx = std::clamp(ix + dx, 0, white.nx() - 1);
						const int jy = std::clamp(iy + dy, 0, white.ny() - 1);
						s += k[dx + 1] * k[dy + 1] * white.at(jx, jy);
					}
				// std of the smoothed white noise is sqrt(sum k^2) = 0.375
				rough.at(ix, iy) =
				    s / 0.375 * o.roughness_m *
				    roughness_factor(rough.xOf(ix), rough.yOf(iy));
			}
	}
	// One grid for the full surface: half the look-ups per height query,
	// and the same surface (a bilinear cell restricted to an aligned sub-cell
	// is bilinear on it).
	full_ = GridField(xmin, ymin, rs, rnx, rny);
	for (int iy = 0; iy < full_.ny(); iy++)
		for (int ix = 0; ix < full_.nx(); ix++)
			full_.at(ix, iy) =
			    smooth_.value(full_.xOf(ix), full_.yOf(iy)) + rough.at(ix, iy);
	max_h_ = full_.maxValue() + 1e-6;

	// Upper bound per smooth cell: the highest full-surface node touching
	// the cell (a bilinear interpolant stays below its nodes).
	const int ncx = smooth_.nx() - 1, ncy = smooth_.ny() - 1;
	cell_max_.assign(static_cast<size_t>(ncx) * ncy, 0.f);
	const double ratio = smooth_.step() / full_.step();
	for (int iy = 0; iy < ncy; iy++)
		for (int ix = 0; ix < ncx; ix++)
		{
			double hmax = -1e9;
			const int rx0 =
			    std::max(0, static_cast<int>(std::floor(ix * ratio)));
			const int rx1 = std::min(
			    full_.nx() - 1, static_cast<int>(std::ceil((ix + 1) * ratio)));
			const int ry0 =
			    std::max(0, static_cast<int>(std::floor(iy * ratio)));
			const int ry1 = std::min(
			    full_.ny() - 1, static_cast<int>(std::ceil((iy + 1) * ratio)));
			for (int ry = ry0; ry <= ry1; ry++)
				for (int rx = rx0; rx <= rx1; rx++)
					hmax = std::max(hmax, full_.at(rx, ry));
			cell_max_[static_cast<size_t>(iy) * ncx + ix] =
			    static_cast<float>(hmax + 1e-4);
		}
}

double Terrain::minHeightIn(double x0, double y0, double x1, double y1) const
{
	// A bilinear field stays above the smallest node touching the box.
	auto nodeMin = [&](const GridField& f)
	{
		const int ix0 =
		    std::clamp(static_cast<int>(std::floor((x0 - f.x0()) / f.step())),
		               0, f.nx() - 1);
		const int ix1 =
		    std::clamp(static_cast<int>(std::ceil((x1 - f.x0()) / f.step())), 0,
		               f.nx() - 1);
		const int iy0 =
		    std::clamp(static_cast<int>(std::floor((y0 - f.y0()) / f.step())),
		               0, f.ny() - 1);
		const int iy1 =
		    std::clamp(static_cast<int>(std::ceil((y1 - f.y0()) / f.step())), 0,
		               f.ny() - 1);
		double m = 1e9;
		for (int iy = iy0; iy <= iy1; iy++)
			for (int ix = ix0; ix <= ix1; ix++) m = std::min(m, f.at(ix, iy));
		return m;
	};
	return nodeMin(full_);
}

Eigen::Vector3d Terrain::normal(double x, double y) const
{
	const Eigen::Vector2d g = full_.gradient(x, y);
	return Eigen::Vector3d(-g.x(), -g.y(), 1.0).normalized();
}

bool Terrain::marchCell(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                        double t0, double t1, double& t_hit) const
{
	// Walk the fine cells of full_ crossed over [t0, t1]; in each, the
	// surface is a bilinear patch, so z(t) - h(t) is a quadratic in t whose
	// smallest root in the cell is the exact intersection.
	const double step = full_.step(), inv = 1.0 / step;
	const double x0 = full_.x0(), y0 = full_.y0();
	const int nfx = full_.nx() - 1, nfy = full_.ny() - 1;
	const Eigen::Vector3d p0 = o + t0 * d;
	int ix = std::clamp(static_cast<int>(std::floor((p0.x() - x0) * inv)), 0,
	                    nfx - 1);
	int iy = std::clamp(static_cast<int>(std::floor((p0.y() - y0) * inv)), 0,
	                    nfy - 1);
	const int sx = d.x() > 0 ? 1 : -1, sy = d.y() > 0 ? 1 : -1;
	const double inf = std::numeric_limits<double>::infinity();
	const double dtx = std::abs(d.x()) > 1e-15 ? step / std::abs(d.x()) : inf;
	const double dty = std::abs(d.y()) > 1e-15 ? step / std::abs(d.y()) : inf;
	double tmx = std::abs(d.x()) > 1e-15
	                 ? (x0 + (ix + (sx > 0)) * step - o.x()) / d.x()
	                 : inf;
	double tmy = std::abs(d.y()) > 1e-15
	                 ? (y0 + (iy + (sy > 0)) * step - o.y()) / d.y()
	                 : inf;
	double ta = t0;
	// Patch coordinates u, v in [0,1] are linear in t.
	const double du = d.x() * inv, dv = d.y() * inv;
	while (true)
	{
		const double tb = std::min({tmx, tmy, t1});
		const double h00 = full_.at(ix, iy), h10 = full_.at(ix + 1, iy);
		const double h01 = full_.at(ix, iy + 1), h11 = full_.at(ix + 1, iy + 1);
		const double z_low = o.z() + d.z() * (d.z() >= 0 ? ta : tb);
		if (z_low <= std::max({h00, h10, h01, h11}))
		{
			// f(t) = z(t) - [A + B u + C v + D u v], u = u0 + t du, ...
			const double u0 = (o.x() - (x0 + ix * step)) * inv;
			const double v0 = (o.y() - (y0 + iy * step)) * inv;
			const double A = h00, B = h10 - h00, C = h01 - h00;
			const double D = h00 - h10 - h01 + h11;
			const double a2 = -D * du * dv;
			const double a1 = d.z() - B * du - C * dv - D * (u0 * dv + v0 * du);
			const double a0 = o.z() - A - B * u0 - C * v0 - D * u0 * v0;
			const double f_a = (a2 * ta + a1) * ta + a0;
			if (f_a <= 0)
			{
				t_hit = ta;  // started under the surface
				return true;
			}
			double r[2];
			int n = 0;
			if (std::abs(a2) < 1e-14)
			{
				if (std::abs(a1) > 1e-15) r[n++] = -a0 / a1;
			}
			else
			{
				const double disc = a1 * a1 - 4 * a2 * a0;
				if (disc >= 0)
				{
					const double sq = std::sqrt(disc);
					const double q = -0.5 * (a1 + (a1 >= 0 ? sq : -sq));
					r[n++] = q / a2;
					if (q != 0) r[n++] = a0 / q;
					if (n == 2 && r[0] > r[1]) std::swap(r[0], r[1]);
				}
			}
			for (int k = 0; k < n; k++)
				if (r[k] >= ta - 1e-9 && r[k] <= tb + 1e-9)
				{
					t_hit = std::max(r[k], ta);
					return true;
				}
		}
		if (tb >= t1) return false;
		if (tmx < tmy)
		{
			ix += sx;
			ta = tmx;
			tmx += dtx;
		}
		else
		{
			iy += sy;
			ta = tmy;
			tmy += dty;
		}
		if (ix < 0 || iy < 0 || ix >= nfx || iy >= nfy) return false;
	}
}

bool Terrain::raycast(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                      double t_max, double& t_hit) const
{
	if (o.z() > max_h_ && d.z() >= 0) return false;
	const double step = smooth_.step(), x0 = smooth_.x0(), y0 = smooth_.y0();
	const int ncx = smooth_.nx() - 1, ncy = smooth_.ny() - 1;
	// Clip to the grid rectangle.
	double ta = 0, tb = t_max;
	const double org[2] = {o.x(), o.y()}, dir[2] = {d.x(), d.y()};
	const double lo[2] = {x0, y0}, hi[2] = {x0 + ncx * step, y0 + ncy * step};
	for (int k = 0; k < 2; k++)
	{
		if (std::abs(dir[k]) < 1e-15)
		{
			if (org[k] < lo[k] || org[k] > hi[k]) return false;
			continue;
		}
		double t1 = (lo[k] - org[k]) / dir[k], t2 = (hi[k] - org[k]) / dir[k];
		if (t1 > t2) std::swap(t1, t2);
		ta = std::max(ta, t1);
		tb = std::min(tb, t2);
	}
	if (ta > tb) return false;
	const Eigen::Vector3d p = o + ta * d;
	int ix = std::clamp(static_cast<int>((p.x() - x0) / step), 0, ncx - 1);
	int iy = std::clamp(static_cast<int>((p.y() - y0) / step), 0, ncy - 1);
	const int sx = d.x() > 0 ? 1 : -1, sy = d.y() > 0 ? 1 : -1;
	const double inf = std::numeric_limits<double>::infinity();
	const double dtx = std::abs(d.x()) > 1e-15 ? step / std::abs(d.x()) : inf;
	const double dty = std::abs(d.y()) > 1e-15 ? step / std::abs(d.y()) : inf;
	double tmx = std::abs(d.x()) > 1e-15
	                 ? (x0 + (ix + (sx > 0)) * step - o.x()) / d.x()
	                 : inf;
	double tmy = std::abs(d.y()) > 1e-15
	                 ? (y0 + (iy + (sy > 0)) * step - o.y()) / d.y()
	                 : inf;
	double t_enter = ta;
	while (true)
	{
		const double t_exit = std::min({tmx, tmy, tb});
		// Lowest point of the ray over this cell vs the cell's highest.
		const double z_low = o.z() + d.z() * (d.z() >= 0 ? t_enter : t_exit);
		if (z_low <= cell_max_[static_cast<size_t>(iy) * ncx + ix] &&
		    marchCell(o, d, t_enter, t_exit, t_hit))
			return true;
		if (t_exit >= tb) return false;
		if (d.z() >= 0 && o.z() + d.z() * t_exit > max_h_) return false;
		if (tmx < tmy)
		{
			ix += sx;
			t_enter = tmx;
			tmx += dtx;
		}
		else
		{
			iy += sy;
			t_enter = tmy;
			tmy += dty;
		}
		if (ix < 0 || iy < 0 || ix >= ncx || iy >= ncy) return false;
	}
}

}  // namespace forest_slam::sim
