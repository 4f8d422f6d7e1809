#include <forest_slam/sim/random.h>
#include <forest_slam/sim/scene_builder.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <unordered_map>

namespace forest_slam::sim
{
namespace
{
constexpr double kDeg = M_PI / 180.0;
constexpr double kBelowGround = 0.3;  ///< stems start under the surface
}  // namespace

PathDistance::PathDistance(const std::vector<Eigen::Vector2d>& samples,
                           double xmin, double ymin, double xmax, double ymax,
                           double cell_m, double cap_m)
    : x0_(xmin), y0_(ymin), inv_(1.0 / cell_m), cap_(cap_m)
{
	nx_ = static_cast<int>(std::ceil((xmax - xmin) * inv_)) + 1;
	ny_ = static_cast<int>(std::ceil((ymax - ymin) * inv_)) + 1;
	d_.assign(static_cast<size_t>(nx_) * ny_, static_cast<float>(cap_m));
	const int r = static_cast<int>(std::ceil(cap_m * inv_)) + 1;
	for (const auto& p : samples)
	{
		const int cx = static_cast<int>(std::floor((p.x() - x0_) * inv_));
		const int cy = static_cast<int>(std::floor((p.y() - y0_) * inv_));
		for (int iy = std::max(0, cy - r); iy <= std::min(ny_ - 1, cy + r);
		     iy++)
			for (int ix = std::max(0, cx - r); ix <= std::min(nx_ - 1, cx + r);
			     ix++)
			{
				const double d = std::hypot(x0_ + (ix + 0.5) / inv_ - p.x(),
				                            y0_ + (iy + 0.5) / inv_ - p.y());
				float& v = d_[static_cast<size_t>(iy) * nx_ + ix];
				if (d < v) v = static_cast<float>(d);
			}
	}
}

double PathDistance::operator()(double x, double y) const
{
	const int ix = static_cast<int>(std::floor((x - x0_) * inv_));
	const int iy = static_cast<int>(std::floor((y - y0_) * inv_));
	if (ix < 0 || iy < 0 || ix >= nx_ || iy >= ny_) return cap_;
	// Cell-centre distance: within half a cell diagonal of the true value.
	return std::max(0.0,
	                d_[static_cast<size_t>(iy) * nx_ + ix] - 0.7071 / inv_);
}

namespace
{
/** Smooth random field in about [-1, 1] (patchy stand density). */
struct Patchiness
{
	double kx[3], ky[3], ph[3];
	explicit Patchiness(Rng& rng)
	{
		for (int i = 0; i < 3; i++)
		{
			const double lambda = rng.uniform(30, 80),
			             dir = rng.uniform(0, M_PI);
			kx[i] = 2 * M_PI / lambda * std::cos(dir);
			ky[i] = 2 * M_PI / lambda * std::sin(dir);
			ph[i] = rng.uniform(0, 2 * M_PI);
		}
	}
	double operator()(double x, double y) const
	{
		double v = 0;
		for (int i = 0; i < 3; i++)
			v += std::sin(kx[i] * x + ky[i] * y + ph[i]);
		return v / 1.5;
	}
};

/** Orthonormal frame with z along `axis`, x rotated by `psi` about it. */
Eigen::Matrix3d frameAlong(const Eigen::Vector3d& axis, double psi)
{
	const Eigen::Vector3d ref = std::abs(axis.x()) < 0.9
	                                ? Eigen::Vector3d::UnitX()
	                                : Eigen::Vector3d::UnitY();
	const Eigen::Vector3d e1 = (ref - ref.dot(axis) * axis).normalized();
	const Eigen::Vector3d e2 = axis.cross(e1);
	const Eigen::Vector3d ex = std::cos(psi) * e1 + std::sin(psi) * e2;
	Eigen::Matrix3d R;
	R.col(0) = ex;
	R.col(1) = axis.cross(ex);
	R.col(2) = axis;
	return R;
}

/** Spatial hash of placed stems for the hard-core test. */
class StemIndex
{
   public:
	StemIndex(double xmin, double ymin, double cell)
	    : x0_(xmin), y0_(ymin), cell_(cell)
	{
	}
	void add(double x, double y, double r)
	{
		pts_.push_back({x, y, r});
		grid_[key(cellOf(x, x0_), cellOf(y, y0_))].push_back(pts_.size() - 1);
	}
	/** Min over stems of (centre distance - r_other - r). */
	double clearance(double x, double y, double r, double search) const
	{
		double best = 1e9;
		const int n = static_cast<int>(std::ceil(search / cell_));
		const int cx = cellOf(x, x0_), cy = cellOf(y, y0_);
		for (int iy = cy - n; iy <= cy + n; iy++)
			for (int ix = cx - n; ix <= cx + n; ix++)
			{
				const auto it = grid_.find(key(ix, iy));
				if (it == grid_.end()) continue;
				for (size_t i : it->second)
				{
					const auto& p = pts_[i];
					best = std::min(best,
					                std::hypot(p[0] - x, p[1] - y) - p[2] - r);
				}
			}
		return best;
	}

   private:
	int cellOf(double v, double v0) const
	{
		return static_cast<int>(std::floor((v - v0) / cell_));
	}
	static int64_t key(int ix, int iy)
	{
		// Shifted as unsigned: a left shift of a negative int64 is undefined
		// before C++20 (UBSan, make test-asan).
		return static_cast<int64_t>((uint64_t(uint32_t(ix)) << 32) |
		                            uint64_t(uint32_t(iy)));
	}
	double x0_, y0_, cell_;
	std::vector<std::array<double, 3>> pts_;
	std::unordered_map<int64_t, std::vector<size_t>> grid_;
};

struct Builder
{
	const SimOptions& o;
	World& world;
	const Terrain& terrain;
	const PathDistance& path_d;
	const PathDistance& trail_d;
	double xmin, ymin, xmax, ymax;

	bool inYard(double x, double y, double margin) const
	{
		return std::hypot(x, y) < o.world.open_area_radius_m + margin;
	}
	bool onTrail(double x, double y, double margin) const
	{
		return o.trail.length_m > 0 &&
		       trail_d(x, y) < 0.5 * o.trail.width_m + margin;
	}

	/** A stem as stacked elliptic frusta along a leaning axis; returns the
	 * truth record. `profile` lists (height above ground, radius factor). */
	void addStem(const TreeTruth& t, const Eigen::Matrix3d& R, double sa,
	             double sb, double r,
	             const std::vector<std::pair<double, double>>& profile,
	             double bark_amp, Rng& rng)
	{
		const Eigen::Vector3d a = R.col(2);
		const Eigen::Vector3d base = t.ground - kBelowGround * a;
		const double phase = rng.uniform(0, 2 * M_PI);
		const int ridges = 5 + static_cast<int>(t.dbh_m * 20);
		const float refl = static_cast<float>(rng.uniform(38, 55));
		for (size_t i = 0; i + 1 < profile.size(); i++)
		{
			StemSegment s;
			s.base = base;
			s.R = R;
			s.z0 = profile[i].first + kBelowGround;
			s.z1 = profile[i + 1].first + kBelowGround;
			if (s.z1 <= s.z0) continue;
			s.r0 = std::max(profile[i].second * r, 0.002);
			s.r1 = std::max(profile[i + 1].second * r, 0.002);
			s.sa = sa;
			s.sb = sb;
			s.bark_amp = bark_amp;
			s.bark_phase = phase;
			s.bark_ridges = ridges;
			s.tree = static_cast<uint16_t>(t.id + 1);
			s.reflectivity = refl;
			s.label = kLabelStem;
			world.add(s);
		}
	}

	void addTree(TreeTruth& t, Rng& rng)
	{
		const auto& to = o.trees;
		const double lean = rng.uniform(0, to.lean_max_deg) * kDeg;
		const double lean_dir = rng.uniform(0, 2 * M_PI);
		const Eigen::Vector3d a(std::sin(lean) * std::cos(lean_dir),
		                        std::sin(lean) * std::sin(lean_dir),
		                        std::cos(lean));
		const double e = rng.uniform(0, to.ellipticity_max);
		const Eigen::Matrix3d R = frameAlong(a, rng.uniform(0, M_PI));
		const double r = 0.5 * t.dbh_m, H = t.height_m;
		const double cb =
		    std::clamp(H * rng.uniform(to.crown_base_min_fraction,
		                               to.crown_base_max_fraction),
		               3.0, 0.8 * H);
		// Butt swell below 0.8 m, constant 0.8-1.8 m (so DBH is exact over
		// any 1.2-1.4 m slice on slopes), then taper to the tip.
		const std::vector<std::pair<double, double>> profile = {
		    {-kBelowGround, 1.2}, {0.0, 1.2}, {0.8, 1.0},
		    {1.8, 1.0},           {cb, 0.8},  {0.85 * H, 0.3},
		    {H, 0.004 / r}};
		addStem(t, R, 1 + e, 1 - e, r, profile, to.bark_roughness_m, rng);
		t.lean_deg = lean / kDeg;
		t.ellipticity = e;
		const double s13 = (1.3 + kBelowGround * a.z()) / a.z();  // axial
		const Eigen::Vector3d base = t.ground - kBelowGround * a;
		t.breast_xy = (base + s13 * a).head<2>();
		auto axisAt = [&](double h) -> Eigen::Vector3d
		{ return base + ((h + kBelowGround) / a.z()) * a; };
		const uint16_t tid = static_cast<uint16_t>(t.id + 1);

		// Crown: three stacked foliage ellipsoids approximating a cone.
		const double Rc =
		    std::max(to.crown_radius_min_m, to.crown_radius_per_dbh * t.dbh_m) *
		    rng.uniform(0.85, 1.15);
		const double Lc = H - cb;
		const double layers[3][3] = {
		    {0.3, 0.9, 0.35}, {0.6, 0.6, 0.25}, {0.85, 0.3, 0.18}};
		for (const auto& L : layers)
		{
			Medium m;
			m.center = axisAt(cb + L[0] * Lc);
			m.radii = Eigen::Vector3d(L[1] * Rc, L[1] * Rc, L[2] * Lc);
			m.extinction_per_m = to.crown_extinction_per_m;
			m.tree = tid;
			m.reflectivity = static_cast<float>(rng.uniform(25, 40));
			m.label = kLabelCrown;
			world.add(m);
		}
		// Live branches in whorls, length following the crown cone.
		for (double h = cb + rng.uniform(0, to.whorl_spacing_m); h < H - 0.5;
		     h += to.whorl_spacing_m * rng.uniform(0.8, 1.2))
		{
			const double az0 = rng.uniform(0, 2 * M_PI);
			const double r_here =
			    r * (0.8 - 0.5 * (h - cb) / std::max(Lc, 1e-3));
			for (int j = 0; j < to.branches_per_whorl; j++)
			{
				const double az = az0 + 2 * M_PI * j / to.branches_per_whorl +
				                  rng.uniform(-0.3, 0.3);
				const double el = rng.uniform(-25, 10) * kDeg;
				const double len =
				    std::max(0.3, Rc * (H - h) / std::max(Lc, 1e-3) *
				                      rng.uniform(0.7, 1.0));
				Cylinder c;
				c.p0 = axisAt(h);
				c.axis =
				    Eigen::Vector3d(std::cos(el) * std::cos(az),
				                    std::cos(el) * std::sin(az), std::sin(el));
				c.length = len;
				c.radius = std::clamp(
				    to.branch_radius_max_m * len / Rc * rng.uniform(0.7, 1.0),
				    0.006, std::max(0.006, 0.6 * r_here));
				c.tree = tid;
				c.reflectivity = static_cast<float>(rng.uniform(35, 50));
				c.label = kLabelCrown;
				world.add(c);
			}
		}
		// Dead branches between dead_branch_min_height_m and the crown.
		const double h_dead = std::max(to.dead_branch_min_height_m, 0.5);
		const int n_dead = cb > h_dead
		                       ? static_cast<int>(std::round(
		                             to.dead_branches_per_m * (cb - h_dead)))
		                       : 0;
		for (int j = 0; j < n_dead; j++)
		{
			const double h = rng.uniform(h_dead, cb);
			const double az = rng.uniform(0, 2 * M_PI),
			             el = rng.uniform(-10, 30) * kDeg;
			Cylinder c;
			c.p0 = axisAt(h);
			c.axis = Eigen::Vector3d(std::cos(el) * std::cos(az),
			                         std::cos(el) * std::sin(az), std::sin(el));
			c.length = r + rng.uniform(0.3, 1.2);
			c.radius = rng.uniform(0.006, 0.015);
			c.tree = tid;
			c.reflectivity = static_cast<float>(rng.uniform(30, 45));
			c.label = kLabelCrown;
			world.add(c);
		}
	}

	void addSapling(TreeTruth& t, Rng& rng)
	{
		const double lean = rng.uniform(0, o.trees.lean_max_deg) * kDeg;
		const double lean_dir = rng.uniform(0, 2 * M_PI);
		const Eigen::Vector3d a(std::sin(lean) * std::cos(lean_dir),
		                        std::sin(lean) * std::sin(lean_dir),
		                        std::cos(lean));
		const Eigen::Matrix3d R = frameAlong(a, rng.uniform(0, M_PI));
		const double H = t.height_m, r_top = 0.003;
		// Linear taper through dbh/2 at 1.3 m (or a thin stem if shorter).
		const double r13 = t.dbh_m > 0 ? 0.5 * t.dbh_m : 0.006;
		const double f = std::min(1.3 / H, 0.9);
		const double r_base = std::max((r13 - r_top * f) / (1 - f), r13);
		const std::vector<std::pair<double, double>> profile = {
		    {-kBelowGround, r_base / r13},
		    {0.0, r_base / r13},
		    {H, r_top / r13}};
		addStem(t, R, 1, 1, r13, profile, 0.0, rng);
		t.lean_deg = lean / kDeg;
		const Eigen::Vector3d base = t.ground - kBelowGround * a;
		t.breast_xy = (base + ((1.3 + kBelowGround) / a.z()) * a).head<2>();
		Medium m;
		m.center = base + ((0.65 * H + kBelowGround) / a.z()) * a;
		const double rc = rng.uniform(0.3, 0.8) * std::min(1.0, H / 4);
		m.radii = Eigen::Vector3d(rc, rc, 0.3 * H);
		m.extinction_per_m = o.saplings.crown_extinction_per_m;
		m.tree = static_cast<uint16_t>(t.id + 1);
		m.reflectivity = static_cast<float>(rng.uniform(25, 40));
		m.label = kLabelCrown;
		world.add(m);
	}
};

Eigen::Vector2d uniformIn(Rng& rng, double xmin, double ymin, double xmax,
                          double ymax)
{
	const double x = rng.uniform(xmin, xmax);
	return {x, rng.uniform(ymin, ymax)};
}
}  // namespace

Scene buildScene(const SimOptions& o, const PathPlan& path, Rng& rng)
{
	Scene scene;
	const auto samples = path.sample(0.25);
	double xmin = 1e9, ymin = 1e9, xmax = -1e9, ymax = -1e9;
	for (const auto& p : samples)
	{
		xmin = std::min(xmin, p.x());
		ymin = std::min(ymin, p.y());
		xmax = std::max(xmax, p.x());
		ymax = std::max(ymax, p.y());
	}
	const double yard = o.world.open_area_radius_m;
	xmin = std::min(xmin, -yard) - o.world.margin_m;
	ymin = std::min(ymin, -yard) - o.world.margin_m;
	xmax = std::max(xmax, yard) + o.world.margin_m;
	ymax = std::max(ymax, yard) + o.world.margin_m;

	// Trail: the first and last trail.length_m of the route.
	std::vector<Eigen::Vector2d> trail;
	if (o.trail.length_m > 0)
	{
		const double L = path.length(),
		             tl = std::min(o.trail.length_m, 0.5 * L);
		for (double s = 0; s <= tl; s += 0.25) trail.push_back(path.point(s));
		for (double s = L - tl; s <= L; s += 0.25)
			trail.push_back(path.point(s));
	}
	const double cap = 6.0;
	const PathDistance path_d(samples, xmin, ymin, xmax, ymax, 0.25, cap);
	const PathDistance trail_d(trail, xmin, ymin, xmax, ymax, 0.25, cap);

	Rng rng_terrain = rng.fork(1);
	const double trail_half = 0.5 * o.trail.width_m;
	auto roughness = [&](double x, double y)
	{
		if (std::hypot(x, y) < yard) return 0.3;  // gravel yard
		if (!trail.empty() && trail_d(x, y) < trail_half)
			return o.trail.roughness_factor;
		return 1.0;
	};
	auto terrain = std::make_unique<Terrain>(o.terrain, xmin, ymin, xmax, ymax,
	                                         yard, std::max(15.0, 0.6 * yard),
	                                         roughness, rng_terrain);
	const Terrain& ter = *terrain;
	scene.stats.terrain_elevation_range_m = ter.stats().elevation_range_m;
	scene.stats.terrain_max_slope_deg = ter.stats().max_slope_deg;
	scene.world =
	    std::make_unique<World>(std::move(terrain), xmin, ymin, xmax, ymax);
	World& world = *scene.world;
	Builder b{o,    world, world.terrain(), path_d, trail_d, xmin, ymin,
	          xmax, ymax};
	// Footprints (x, y, radius) of buildings and vehicles: vegetation keeps
	// clear of them.
	std::vector<std::array<double, 3>> placed;
	auto nearStructure = [&](double x, double y, double r)
	{
		for (const auto& q : placed)
			if (std::hypot(q[0] - x, q[1] - y) < q[2] + r + 1.0) return true;
		return false;
	};

	const double area = (xmax - xmin) * (ymax - ymin);
	const double forest_area = std::max(1.0, area - M_PI * yard * yard);
	scene.stats.forest_area_ha = forest_area / 1e4;

	// Buildings and vehicles in the yard, clear of the route.
	Rng rng_st = rng.fork(5);
	const auto& st = o.structures;
	auto clearOfRoute = [&](const Eigen::Vector2d& c, double rad)
	{
		for (const auto& s : samples)
			if ((s - c).norm() < rad + st.path_clearance_m) return false;
		for (const auto& q : placed)
			if (std::hypot(q[0] - c.x(), q[1] - c.y()) < rad + q[2] + 2.0)
				return false;
		return true;
	};
	auto place = [&](double sx, double sy)
	{
		const double rad = 0.5 * std::hypot(sx, sy);
		for (int attempt = 0; attempt < 400; attempt++)
		{
			const double ang = rng_st.uniform(0, 2 * M_PI);
			const double rho = yard * std::sqrt(rng_st.uniform());
			const Eigen::Vector2d c(rho * std::cos(ang), rho * std::sin(ang));
			const double yaw = rng_st.uniform(0, M_PI);
			if (!clearOfRoute(c, rad)) continue;
			placed.push_back({c.x(), c.y(), rad});
			return std::make_pair(c, yaw);
		}
		return std::make_pair(Eigen::Vector2d(1e9, 1e9), 0.0);
	};
	for (int i = 0; i < st.buildings; i++)
	{
		const double sx =
		    rng_st.uniform(st.building_size_min_m, st.building_size_max_m);
		const double sy =
		    rng_st.uniform(st.building_size_min_m, st.building_size_max_m);
		const double h =
		    rng_st.uniform(st.building_height_min_m, st.building_height_max_m);
		const auto [c, yaw] = place(sx, sy);
		if (c.x() > 1e8) continue;
		const double zg = ter.height(c.x(), c.y()) - 0.2;
		Box box;
		box.center = Eigen::Vector3d(c.x(), c.y(), zg + 0.5 * (h + 0.2));
		box.half = Eigen::Vector3d(0.5 * sx, 0.5 * sy, 0.5 * (h + 0.2));
		box.yaw = yaw;
		box.reflectivity = static_cast<float>(rng_st.uniform(55, 90));
		world.add(box);
		scene.stats.buildings++;
	}
	for (int i = 0; i < st.vehicles; i++)
	{
		const double len = rng_st.uniform(4.2, 5.0),
		             wid = rng_st.uniform(1.7, 1.9);
		const auto [c, yaw] = place(len, wid);
		if (c.x() > 1e8) continue;
		const double zg = ter.height(c.x(), c.y());
		// Painted body (bright) and a cabin on top.
		Box body;
		body.center = Eigen::Vector3d(c.x(), c.y(), zg + 0.25 + 0.45);
		body.half = Eigen::Vector3d(0.5 * len, 0.5 * wid, 0.45);
		body.yaw = yaw;
		body.reflectivity = static_cast<float>(rng_st.uniform(80, 130));
		world.add(body);
		Box cabin = body;
		cabin.center.z() = zg + 0.25 + 0.9 + 0.3;
		cabin.half = Eigen::Vector3d(0.28 * len, 0.47 * wid, 0.3);
		cabin.reflectivity =
		    static_cast<float>(rng_st.uniform(15, 30));  // glass
		world.add(cabin);
		scene.stats.vehicles++;
	}

	// Trees: hard-core process with patchy acceptance.
	Rng rng_trees = rng.fork(2);
	const Patchiness patch(rng_trees);
	StemIndex stems(xmin, ymin, 2.0);
	const auto& to = o.trees;
	const int target =
	    static_cast<int>(std::round(to.stems_per_ha * forest_area / 1e4));
	const double search = to.hard_core_m + to.dbh_max_m * 1.2 + 0.1;
	// Plantation: the grid positions in row order (rows along the azimuth).
	std::vector<Eigen::Vector2d> grid;
	if (to.layout == "rows")
	{
		const double a = to.row_azimuth_deg * M_PI / 180;
		const Eigen::Vector2d u(std::cos(a), std::sin(a)), v(-u.y(), u.x());
		const double R = std::hypot(xmax - xmin, ymax - ymin);
		// Rows offset by half a spacing from the start (the route runs
		// between two rows).
		for (double b = -R + 0.5 * to.row_spacing_m; b <= R;
		     b += to.row_spacing_m)
			for (double t = -R; t <= R; t += to.row_tree_spacing_m)
			{
				const Eigen::Vector2d q = t * u + b * v;
				if (q.x() > xmin + 1 && q.x() < xmax - 1 && q.y() > ymin + 1 &&
				    q.y() < ymax - 1)
					grid.push_back(q);
			}
	}
	const long attempts =
	    grid.empty() ? 60L * target : static_cast<long>(grid.size());
	for (long attempt = 0;
	     attempt < attempts &&
	     (!grid.empty() || static_cast<int>(scene.trees.size()) < target);
	     attempt++)
	{
		Eigen::Vector2d p;
		if (grid.empty())
			p = uniformIn(rng_trees, xmin + 1, ymin + 1, xmax - 1, ymax - 1);
		else
			p = grid[attempt] + Eigen::Vector2d(rng_trees.uniform(-1, 1),
			                                    rng_trees.uniform(-1, 1)) *
			                        to.row_jitter_m;
		const double dbh =
		    std::clamp(rng_trees.lognormal(to.dbh_median_m, to.dbh_sigma_log),
		               to.dbh_min_m, to.dbh_max_m);
		const double accept = rng_trees.uniform();
		const double r = 0.6 * dbh;  // with butt swell
		if (b.inYard(p.x(), p.y(), 2 + r)) continue;
		if (nearStructure(p.x(), p.y(), r)) continue;
		if (path_d(p.x(), p.y()) < to.path_clearance_m + r) continue;
		if (b.onTrail(p.x(), p.y(), 0.5 + r)) continue;
		if (grid.empty() && accept * (1 + to.density_variation) >
		                        1 + to.density_variation * patch(p.x(), p.y()))
			continue;
		if (stems.clearance(p.x(), p.y(), r, search) < to.hard_core_m) continue;
		if (scene.trees.size() >= 65000)
			throw std::runtime_error(
			    "too many trees for the 16-bit gt_tree layer");
		TreeTruth t;
		t.id = static_cast<int>(scene.trees.size());
		t.ground = Eigen::Vector3d(p.x(), p.y(), ter.height(p.x(), p.y()));
		t.dbh_m = dbh;
		// Height grows with DBH (saturating), plus noise.
		const double x =
		    (dbh - to.dbh_min_m) / std::max(1e-6, to.dbh_max_m - to.dbh_min_m);
		t.height_m = std::clamp(
		    to.height_min_m +
		        (to.height_max_m - to.height_min_m) * std::pow(x, 0.6) +
		        rng_trees.normal(0, to.height_noise_m),
		    to.height_min_m, to.height_max_m);
		b.addTree(t, rng_trees);
		stems.add(p.x(), p.y(), r);
		scene.trees.push_back(t);
	}
	scene.stats.trees = static_cast<int>(scene.trees.size());
	scene.stats.stems_per_ha = scene.stats.trees / scene.stats.forest_area_ha;

	// Saplings.
	Rng rng_sap = rng.fork(3);
	const auto& so = o.saplings;
	const int n_sap =
	    static_cast<int>(std::round(so.per_ha * forest_area / 1e4));
	for (long attempt = 0;
	     attempt < 30L * n_sap && scene.stats.saplings < n_sap; attempt++)
	{
		const Eigen::Vector2d p =
		    uniformIn(rng_sap, xmin + 1, ymin + 1, xmax - 1, ymax - 1);
		const double h = rng_sap.uniform(so.height_min_m, so.height_max_m);
		const double dbh = rng_sap.uniform(so.dbh_min_m, so.dbh_max_m);
		if (b.inYard(p.x(), p.y(), 1)) continue;
		if (nearStructure(p.x(), p.y(), 0.5)) continue;
		if (path_d(p.x(), p.y()) < 0.8) continue;
		if (b.onTrail(p.x(), p.y(), 0.3)) continue;
		if (stems.clearance(p.x(), p.y(), 0.05, search) < 1.0) continue;
		if (scene.trees.size() >= 65000)
			throw std::runtime_error(
			    "too many trees for the 16-bit gt_tree layer");
		TreeTruth t;
		t.id = static_cast<int>(scene.trees.size());
		t.ground = Eigen::Vector3d(p.x(), p.y(), ter.height(p.x(), p.y()));
		t.height_m = h;
		t.dbh_m = h > 1.3 ? dbh : 0.0;
		t.sapling = true;
		b.addSapling(t, rng_sap);
		stems.add(p.x(), p.y(), 0.05);
		scene.trees.push_back(t);
		scene.stats.saplings++;
	}

	// Shrub patches until the footprints cover cover_fraction.
	Rng rng_shrub = rng.fork(4);
	const auto& sh = o.shrubs;
	const double target_cover = sh.cover_fraction * forest_area;
	const double raster = 0.5;
	const int rnx = static_cast<int>(std::ceil((xmax - xmin) / raster));
	const int rny = static_cast<int>(std::ceil((ymax - ymin) / raster));
	std::vector<uint8_t> covered(static_cast<size_t>(rnx) * rny, 0);
	double covered_m2 = 0;
	for (int patch_i = 0; patch_i < 100000 && covered_m2 < target_cover;
	     patch_i++)
	{
		const Eigen::Vector2d c = uniformIn(rng_shrub, xmin, ymin, xmax, ymax);
		const double R =
		    rng_shrub.uniform(sh.patch_radius_min_m, sh.patch_radius_max_m);
		const int n = static_cast<int>(
		    std::ceil(0.8 * R * R /
		              (0.25 * std::pow(sh.radius_min_m + sh.radius_max_m, 2))));
		for (int k = 0; k < n && covered_m2 < target_cover; k++)
		{
			const double rr = R * std::sqrt(rng_shrub.uniform()),
			             ang = rng_shrub.uniform(0, 2 * M_PI);
			const Eigen::Vector2d p =
			    c + rr * Eigen::Vector2d(std::cos(ang), std::sin(ang));
			const double r =
			    rng_shrub.uniform(sh.radius_min_m, sh.radius_max_m);
			const double hgt =
			    rng_shrub.uniform(sh.height_min_m, sh.height_max_m);
			const double ry = r * rng_shrub.uniform(0.8, 1.2);
			if (p.x() < xmin || p.y() < ymin || p.x() > xmax || p.y() > ymax)
				continue;
			if (b.inYard(p.x(), p.y(), r)) continue;
			if (nearStructure(p.x(), p.y(), std::max(r, ry))) continue;
			if (path_d(p.x(), p.y()) < sh.path_clearance_m + std::max(r, ry))
				continue;
			if (b.onTrail(p.x(), p.y(), std::max(r, ry))) continue;
			if (stems.clearance(p.x(), p.y(), 0.0, search) < 0.1) continue;
			Medium m;
			m.center = Eigen::Vector3d(
			    p.x(), p.y(), ter.height(p.x(), p.y()) + 0.5 * hgt - 0.1);
			m.radii = Eigen::Vector3d(r, ry, 0.5 * hgt);
			m.extinction_per_m = sh.extinction_per_m;
			m.reflectivity = static_cast<float>(rng_shrub.uniform(28, 45));
			m.label = kLabelShrub;
			world.add(m);
			scene.stats.shrubs++;
			// Footprint on the raster, for the achieved cover fraction.
			const int x0 =
			    std::max(0, static_cast<int>((p.x() - r - xmin) / raster));
			const int x1 = std::min(
			    rnx - 1, static_cast<int>((p.x() + r - xmin) / raster));
			const int y0 =
			    std::max(0, static_cast<int>((p.y() - ry - ymin) / raster));
			const int y1 = std::min(
			    rny - 1, static_cast<int>((p.y() + ry - ymin) / raster));
			for (int iy = y0; iy <= y1; iy++)
				for (int ix = x0; ix <= x1; ix++)
				{
					const double dx = (xmin + (ix + 0.5) * raster - p.x()) / r;
					const double dy = (ymin + (iy + 0.5) * raster - p.y()) / ry;
					uint8_t& cell = covered[static_cast<size_t>(iy) * rnx + ix];
					if (dx * dx + dy * dy <= 1 && !cell)
					{
						cell = 1;
						covered_m2 += raster * raster;
					}
				}
		}
	}
	scene.stats.shrub_cover = covered_m2 / forest_area;

	// Ground reflectivity: leaf litter with 0.5 m patches, brighter trail
	// and gravel yard. A hash of the cell keeps it thread-safe and fixed.
	const uint64_t gseed = rng.fork(6).next();
	const bool has_trail = !trail.empty();
	auto trail_copy = std::make_shared<PathDistance>(trail_d);
	world.setGroundReflectivity(
	    [=](double x, double y)
	    {
		    if (std::hypot(x, y) < yard) return 40.f;
		    if (has_trail && (*trail_copy)(x, y) < trail_half) return 35.f;
		    const int64_t cx = static_cast<int64_t>(std::floor(x * 2));
		    const int64_t cy = static_cast<int64_t>(std::floor(y * 2));
		    const double u = hashUniform(
		        hashCombine(gseed, (uint64_t(cx) << 32) ^ uint32_t(cy)));
		    return static_cast<float>(15 + 20 * u);
	    });
	world.finalize(o.world.grid_cell_m);
	return scene;
}

}  // namespace forest_slam::sim
