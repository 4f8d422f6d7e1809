#include <forest_slam/sim/random.h>
#include <forest_slam/sim/world.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace forest_slam::sim
{
namespace
{
/** Real roots of a t^2 + b t + c = 0 in ascending order; returns count. */
int solveQuadratic(double a, double b, double c, double r[2])
{
	if (std::abs(a) < 1e-14)
	{
		if (std::abs(b) < 1e-14) return 0;
		r[0] = -c / b;
		return 1;
	}
	const double disc = b * b - 4 * a * c;
	if (disc < 0) return 0;
	const double sq = std::sqrt(disc);
	// Numerically stable form (no cancellation between -b and sq).
	const double q = -0.5 * (b + (b >= 0 ? sq : -sq));
	double x0 = q / a, x1 = q != 0 ? c / q : x0;
	if (x0 > x1) std::swap(x0, x1);
	r[0] = x0;
	r[1] = x1;
	return 2;
}
}  // namespace

bool intersectStem(const StemSegment& s, const Eigen::Vector3d& o,
                   const Eigen::Vector3d& d, double t_min, double t_max,
                   double& t, double& cos_inc)
{
	const Eigen::Vector3d lo = s.R.transpose() * (o - s.base);
	const Eigen::Vector3d ld = s.R.transpose() * d;
	// Scaling x by 1/sa and y by 1/sb turns the elliptic section into a
	// circle without changing the ray parameter t.
	const double ox = lo.x() / s.sa, oy = lo.y() / s.sb;
	const double dx = ld.x() / s.sa, dy = ld.y() / s.sb;
	const double k = (s.r1 - s.r0) / (s.z1 - s.z0);
	const double q0 = s.r0 + k * (lo.z() - s.z0);
	const double m = k * ld.z();
	auto solve = [&](double q, double& tt)
	{
		double r[2];
		const int n = solveQuadratic(dx * dx + dy * dy - m * m,
		                             2 * (ox * dx + oy * dy - q * m),
		                             ox * ox + oy * oy - q * q, r);
		for (int i = 0; i < n; i++)
		{
			if (r[i] <= t_min || r[i] >= t_max) continue;
			const double z = lo.z() + r[i] * ld.z();
			if (z < s.z0 || z > s.z1 || q + m * r[i] <= 0) continue;
			tt = r[i];
			return true;
		}
		return false;
	};
	double tt;
	if (!solve(q0, tt)) return false;
	if (s.bark_amp > 0)
	{
		// Bark ridges: a radial offset that depends on the angle around the
		// stem and slowly on height; one re-solve with the local offset.
		const double th = std::atan2(oy + tt * dy, ox + tt * dx);
		const double z = lo.z() + tt * ld.z();
		const double delta =
		    s.bark_amp *
		    (0.6 * std::sin(s.bark_ridges * th + s.bark_phase + 0.35 * z) +
		     0.4 * std::sin((2 * s.bark_ridges + 3) * th + 2 * s.bark_phase -
		                    0.6 * z));
		double t2;
		if (solve(q0 + delta, t2)) tt = t2;
	}
	const double X = ox + tt * dx, Y = oy + tt * dy;
	const double r = q0 + m * tt;
	const Eigen::Vector3d n =
	    Eigen::Vector3d(X / s.sa, Y / s.sb, -k * r).normalized();
	cos_inc = static_cast<float>(std::abs(n.dot(ld)));
	t = tt;
	return true;
}

bool intersectCylinder(const Cylinder& c, const Eigen::Vector3d& o,
                       const Eigen::Vector3d& d, double t_min, double t_max,
                       double& t, double& cos_inc)
{
	const Eigen::Vector3d oc = o - c.p0;
	const double da = d.dot(c.axis), oa = oc.dot(c.axis);
	const Eigen::Vector3d dp = d - da * c.axis, op = oc - oa * c.axis;
	const double a = dp.squaredNorm();
	if (a < 1e-14) return false;
	double r[2];
	const int n = solveQuadratic(a, 2 * dp.dot(op),
	                             op.squaredNorm() - c.radius * c.radius, r);
	for (int i = 0; i < n; i++)
	{
		if (r[i] <= t_min || r[i] >= t_max) continue;
		const double s = oa + r[i] * da;
		if (s < 0 || s > c.length) continue;
		const Eigen::Vector3d nrm = (op + r[i] * dp) / c.radius;
		cos_inc = std::min(1.0, std::abs(nrm.dot(d)));
		t = r[i];
		return true;
	}
	return false;
}

bool intersectEllipsoid(const Medium& m, const Eigen::Vector3d& o,
                        const Eigen::Vector3d& d, double t_min, double& t_in,
                        double& t_out)
{
	const Eigen::Vector3d lo = (o - m.center).cwiseQuotient(m.radii);
	const Eigen::Vector3d ld = d.cwiseQuotient(m.radii);
	double r[2];
	if (solveQuadratic(ld.squaredNorm(), 2 * lo.dot(ld), lo.squaredNorm() - 1,
	                   r) != 2)
		return false;
	t_in = std::max(r[0], t_min);
	t_out = r[1];
	return t_out > t_in;
}

bool intersectBox(const Box& b, const Eigen::Vector3d& o,
                  const Eigen::Vector3d& d, double t_min, double t_max,
                  double& t, double& cos_inc)
{
	const double cy = std::cos(b.yaw), sy = std::sin(b.yaw);
	const Eigen::Vector3d p = o - b.center;
	const double lo[3] = {cy * p.x() + sy * p.y(), -sy * p.x() + cy * p.y(),
	                      p.z()};
	const double ld[3] = {cy * d.x() + sy * d.y(), -sy * d.x() + cy * d.y(),
	                      d.z()};
	double t_near = -std::numeric_limits<double>::infinity();
	double t_far = std::numeric_limits<double>::infinity();
	int axis = -1;
	for (int i = 0; i < 3; i++)
	{
		if (std::abs(ld[i]) < 1e-12)
		{
			if (std::abs(lo[i]) > b.half[i]) return false;
			continue;
		}
		double t1 = (-b.half[i] - lo[i]) / ld[i],
		       t2 = (b.half[i] - lo[i]) / ld[i];
		if (t1 > t2) std::swap(t1, t2);
		if (t1 > t_near)
		{
			t_near = t1;
			axis = i;
		}
		t_far = std::min(t_far, t2);
		if (t_near > t_far) return false;
	}
	if (axis < 0 || t_near <= t_min || t_near >= t_max) return false;
	t = t_near;
	cos_inc = std::abs(ld[axis]);
	return true;
}

World::World(std::unique_ptr<Terrain> terrain, double xmin, double ymin,
             double xmax, double ymax)
    : terrain_(std::move(terrain)),
      xmin_(xmin),
      ymin_(ymin),
      xmax_(xmax),
      ymax_(ymax)
{
	ground_reflectivity_ = [](double, double) { return 25.f; };
}

void World::insert(uint32_t id, double x0, double y0, double x1, double y1,
                   double z0, double z1,
                   std::vector<std::vector<Entry>>& cells) const
{
	const int ix0 = std::clamp(
	    static_cast<int>(std::floor((x0 - xmin_) * inv_cell_)), 0, nx_ - 1);
	const int ix1 = std::clamp(
	    static_cast<int>(std::floor((x1 - xmin_) * inv_cell_)), 0, nx_ - 1);
	const int iy0 = std::clamp(
	    static_cast<int>(std::floor((y0 - ymin_) * inv_cell_)), 0, ny_ - 1);
	const int iy1 = std::clamp(
	    static_cast<int>(std::floor((y1 - ymin_) * inv_cell_)), 0, ny_ - 1);
	const Entry e{static_cast<float>(z0 - 1e-3), static_cast<float>(z1 + 1e-3),
	              id};
	const int b0 = bandOf(z0 - 1e-3), b1 = bandOf(z1 + 1e-3);
	for (int iy = iy0; iy <= iy1; iy++)
		for (int ix = ix0; ix <= ix1; ix++)
			for (int b = b0; b <= b1; b++)
				cells[(static_cast<size_t>(iy) * nx_ + ix) * n_bands_ + b]
				    .push_back(e);
}

void World::finalize(double cell_m)
{
	cell_ = cell_m;
	inv_cell_ = 1.0 / cell_m;
	nx_ = std::max(1, static_cast<int>(std::ceil((xmax_ - xmin_) * inv_cell_)));
	ny_ = std::max(1, static_cast<int>(std::ceil((ymax_ - ymin_) * inv_cell_)));
	off_cyl_ = static_cast<uint32_t>(stems_.size());
	off_med_ = off_cyl_ + static_cast<uint32_t>(cylinders_.size());
	off_box_ = off_med_ + static_cast<uint32_t>(media_.size());
	n_total_ = off_box_ + static_cast<uint32_t>(boxes_.size());

	// Height bands over the span of all primitives.
	double zlo = 1e9, zhi = -1e9;
	auto span = [&](double a, double b)
	{
		zlo = std::min(zlo, a);
		zhi = std::max(zhi, b);
	};
	for (const auto& s : stems_)
	{
		const Eigen::Vector3d a = s.base + s.z0 * s.R.col(2),
		                      b = s.base + s.z1 * s.R.col(2);
		const double r =
		    std::max(s.r0, s.r1) * std::max(s.sa, s.sb) + s.bark_amp;
		span(std::min(a.z(), b.z()) - r, std::max(a.z(), b.z()) + r);
	}
	for (const auto& c : cylinders_)
	{
		const double z1 = c.p0.z() + c.length * c.axis.z();
		span(std::min(c.p0.z(), z1) - c.radius,
		     std::max(c.p0.z(), z1) + c.radius);
	}
	for (const auto& m : media_)
		span(m.center.z() - m.radii.z(), m.center.z() + m.radii.z());
	for (const auto& b : boxes_)
		span(b.center.z() - b.half.z(), b.center.z() + b.half.z());
	if (zlo > zhi) zlo = zhi = 0;
	band_z0_ = zlo - 1.0;
	n_bands_ = std::max(
	    1, static_cast<int>(std::ceil((zhi + 1.0 - band_z0_) * inv_band_h_)));

	std::vector<std::vector<Entry>> cells(static_cast<size_t>(nx_) * ny_ *
	                                      n_bands_);
	for (uint32_t i = 0; i < stems_.size(); i++)
	{
		const auto& s = stems_[i];
		const Eigen::Vector3d a = s.R.col(2);
		const Eigen::Vector3d p0 = s.base + s.z0 * a, p1 = s.base + s.z1 * a;
		const double r =
		    std::max(s.r0, s.r1) * std::max(s.sa, s.sb) + s.bark_amp + 1e-3;
		insert(i, std::min(p0.x(), p1.x()) - r, std::min(p0.y(), p1.y()) - r,
		       std::max(p0.x(), p1.x()) + r, std::max(p0.y(), p1.y()) + r,
		       std::min(p0.z(), p1.z()) - r, std::max(p0.z(), p1.z()) + r,
		       cells);
	}
	for (uint32_t i = 0; i < cylinders_.size(); i++)
	{
		const auto& c = cylinders_[i];
		const Eigen::Vector3d p1 = c.p0 + c.length * c.axis;
		const double r = c.radius + 1e-3;
		insert(off_cyl_ + i, std::min(c.p0.x(), p1.x()) - r,
		       std::min(c.p0.y(), p1.y()) - r, std::max(c.p0.x(), p1.x()) + r,
		       std::max(c.p0.y(), p1.y()) + r, std::min(c.p0.z(), p1.z()) - r,
		       std::max(c.p0.z(), p1.z()) + r, cells);
	}
	for (uint32_t i = 0; i < media_.size(); i++)
	{
		const auto& m = media_[i];
		insert(off_med_ + i, m.center.x() - m.radii.x(),
		       m.center.y() - m.radii.y(), m.center.x() + m.radii.x(),
		       m.center.y() + m.radii.y(), m.center.z() - m.radii.z(),
		       m.center.z() + m.radii.z(), cells);
	}
	for (uint32_t i = 0; i < boxes_.size(); i++)
	{
		const auto& b = boxes_[i];
		const double c = std::abs(std::cos(b.yaw)),
		             s = std::abs(std::sin(b.yaw));
		const double ex = c * b.half.x() + s * b.half.y();
		const double ey = s * b.half.x() + c * b.half.y();
		insert(off_box_ + i, b.center.x() - ex, b.center.y() - ey,
		       b.center.x() + ex, b.center.y() + ey, b.center.z() - b.half.z(),
		       b.center.z() + b.half.z(), cells);
	}
	cell_ground_min_.resize(static_cast<size_t>(nx_) * ny_);
	for (int iy = 0; iy < ny_; iy++)
		for (int ix = 0; ix < nx_; ix++)
			cell_ground_min_[static_cast<size_t>(iy) * nx_ + ix] =
			    static_cast<float>(terrain_->minHeightIn(
			                           xmin_ + ix * cell_, ymin_ + iy * cell_,
			                           xmin_ + (ix + 1) * cell_,
			                           ymin_ + (iy + 1) * cell_) -
			                       1e-3);
	cell_start_.assign(cells.size() + 1, 0);
	size_t total = 0;
	for (size_t c = 0; c < cells.size(); c++)
	{
		cell_start_[c] = static_cast<uint32_t>(total);
		total += cells[c].size();
	}
	cell_start_[cells.size()] = static_cast<uint32_t>(total);
	entries_.clear();
	entries_.reserve(total);
	cell_zmin_.assign(static_cast<size_t>(nx_) * ny_, 1e9f);
	cell_zmax_.assign(static_cast<size_t>(nx_) * ny_, -1e9f);
	for (size_t c = 0; c < cells.size(); c++)
	{
		const size_t xy = c / n_bands_;
		for (const auto& e : cells[c])
		{
			cell_zmin_[xy] = std::min(cell_zmin_[xy], e.zmin);
			cell_zmax_[xy] = std::max(cell_zmax_[xy], e.zmax);
			zmax_all_ = std::max(zmax_all_, static_cast<double>(e.zmax));
		}
		entries_.insert(entries_.end(), cells[c].begin(), cells[c].end());
	}
}

void World::intersect(uint32_t id, const Eigen::Vector3d& o,
                      const Eigen::Vector3d& d, double t_min, uint64_t ray_key,
                      Hit& best) const
{
	double t, cos_inc;
	if (id < off_cyl_)
	{
		const auto& s = stems_[id];
		if (intersectStem(s, o, d, t_min, best.t, t, cos_inc))
			best = {t, s.label, s.tree, s.reflectivity,
			        static_cast<float>(cos_inc)};
	}
	else if (id < off_med_)
	{
		const auto& c = cylinders_[id - off_cyl_];
		if (intersectCylinder(c, o, d, t_min, best.t, t, cos_inc))
			best = {t, c.label, c.tree, c.reflectivity,
			        static_cast<float>(cos_inc)};
	}
	else if (id < off_box_)
	{
		const auto& m = media_[id - off_med_];
		double t_in, t_out;
		if (m.extinction_per_m <= 0 ||
		    !intersectEllipsoid(m, o, d, t_min, t_in, t_out) || t_in >= best.t)
			return;
		const uint64_t h = hashCombine(ray_key, id);
		const double free_path =
		    -std::log1p(-hashUniform(h)) / m.extinction_per_m;
		t = t_in + free_path;
		if (t < t_out && t < best.t)
			// Leaves face every way: the incidence cosine is random.
			best = {
			    t,
			    m.label,
			    m.tree,
			    m.reflectivity,
			    static_cast<float>(0.3 + 0.7 * hashUniform(h ^ 0xa5a5a5a5ULL)),
			    true};
	}
	else
	{
		const auto& b = boxes_[id - off_box_];
		if (intersectBox(b, o, d, t_min, best.t, t, cos_inc))
			best = {t, b.label, 0, b.reflectivity, static_cast<float>(cos_inc)};
	}
}

Hit World::raycast(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                   double t_min, double t_max, uint64_t ray_key,
                   RayScratch& scratch, bool with_terrain) const
{
	Hit best;
	best.t = t_max;
	if (scratch.mailbox.size() != n_total_)
	{
		scratch.mailbox.assign(n_total_, 0);
		scratch.stamp = 0;
	}
	if (++scratch.stamp == 0)
	{
		std::fill(scratch.mailbox.begin(), scratch.mailbox.end(), 0);
		scratch.stamp = 1;
	}
	const uint32_t stamp = scratch.stamp;

	// Clip the ray to the grid rectangle (2D slabs).
	const double gx1 = xmin_ + nx_ * cell_, gy1 = ymin_ + ny_ * cell_;
	double ta = t_min, tb = t_max;
	const double dir[2] = {d.x(), d.y()}, org[2] = {o.x(), o.y()};
	const double lo[2] = {xmin_, ymin_}, hi[2] = {gx1, gy1};
	bool inside = nx_ > 0 && ny_ > 0;
	for (int k = 0; k < 2 && inside; k++)
	{
		if (std::abs(dir[k]) < 1e-15)
		{
			if (org[k] < lo[k] || org[k] > hi[k]) inside = false;
			continue;
		}
		double t1 = (lo[k] - org[k]) / dir[k], t2 = (hi[k] - org[k]) / dir[k];
		if (t1 > t2) std::swap(t1, t2);
		ta = std::max(ta, t1);
		tb = std::min(tb, t2);
		if (ta > tb) inside = false;
	}
	if (inside)
	{
		const Eigen::Vector3d p = o + ta * d;
		int ix = std::clamp(static_cast<int>((p.x() - xmin_) * inv_cell_), 0,
		                    nx_ - 1);
		int iy = std::clamp(static_cast<int>((p.y() - ymin_) * inv_cell_), 0,
		                    ny_ - 1);
		const int step_x = d.x() > 0 ? 1 : -1, step_y = d.y() > 0 ? 1 : -1;
		const double inf = std::numeric_limits<double>::infinity();
		const double dtx =
		    std::abs(d.x()) > 1e-15 ? cell_ / std::abs(d.x()) : inf;
		const double dty =
		    std::abs(d.y()) > 1e-15 ? cell_ / std::abs(d.y()) : inf;
		double tmx =
		    std::abs(d.x()) > 1e-15
		        ? (xmin_ + (ix + (step_x > 0 ? 1 : 0)) * cell_ - o.x()) / d.x()
		        : inf;
		double tmy =
		    std::abs(d.y()) > 1e-15
		        ? (ymin_ + (iy + (step_y > 0 ? 1 : 0)) * cell_ - o.y()) / d.y()
		        : inf;
		double t_enter = ta;
		while (true)
		{
			const double t_exit = std::min({tmx, tmy, tb});
			const double za = o.z() + t_enter * d.z(),
			             zb = o.z() + t_exit * d.z();
			const float zlo = static_cast<float>(std::min(za, zb));
			const float zhi = static_cast<float>(std::max(za, zb));
			const size_t c = static_cast<size_t>(iy) * nx_ + ix;
			if (zlo <= cell_zmax_[c] && zhi >= cell_zmin_[c])
			{
				const size_t cb = c * n_bands_;
				const uint32_t e0 = cell_start_[cb + bandOf(zlo)];
				const uint32_t e1 = cell_start_[cb + bandOf(zhi) + 1];
				for (uint32_t e = e0; e < e1; e++)
				{
					const Entry& en = entries_[e];
					if (en.zmax < zlo || en.zmin > zhi) continue;
					if (scratch.mailbox[en.id] == stamp) continue;
					scratch.mailbox[en.id] = stamp;
					intersect(en.id, o, d, t_min, ray_key, best);
				}
			}
			if (best.t <= t_exit || t_exit >= tb) break;
			// Below the ground here: the terrain is hit within this cell.
			if (with_terrain && zlo < cell_ground_min_[c]) break;
			// Rising above everything: nothing further can be hit.
			if (d.z() >= 0 && zhi > zmax_all_) break;
			if (tmx < tmy)
			{
				ix += step_x;
				t_enter = tmx;
				tmx += dtx;
			}
			else
			{
				iy += step_y;
				t_enter = tmy;
				tmy += dty;
			}
			if (ix < 0 || iy < 0 || ix >= nx_ || iy >= ny_) break;
		}
	}
	if (with_terrain)
	{
		double tg;
		if (terrain_->raycast(o, d, best.t, tg) && tg > t_min &&
		    (tg < best.t || !best.valid()))
		{
			const Eigen::Vector3d p = o + tg * d;
			const Eigen::Vector3d n = terrain_->normal(p.x(), p.y());
			best = {tg, kLabelGround, 0, ground_reflectivity_(p.x(), p.y()),
			        static_cast<float>(std::abs(n.dot(d)))};
		}
	}
	if (!best.valid()) best.t = std::numeric_limits<double>::infinity();
	return best;
}

}  // namespace forest_slam::sim
