#include <forest_slam/core/config.h>
#include <forest_slam/core/memory.h>
#include <forest_slam/odometry/local_map.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace forest_slam::odometry
{
size_t LocalMap::memoryBytes() const
{
	size_t n =
	    planar_.memoryBytes() + edges_.memoryBytes() + coarse_.memoryBytes();
	for (const auto* g : {&planar_, &edges_})
		g->forEach([&](Key, const PointCell& c)
		           { n += core::vectorBytes(c.blocks); });
	return n;
}

void LocalMapOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                         const std::string& s)
{
	FS_LOAD(c, s, cell_m);
	FS_LOAD(c, s, planar_spacing_m);
	FS_LOAD(c, s, edge_spacing_m);
	FS_LOAD(c, s, max_points_per_cell);
	FS_LOAD(c, s, min_plane_spread_m);
	FS_LOAD(c, s, coarse_voxel_m);
	FS_LOAD(c, s, max_points_per_voxel);
	FS_LOAD(c, s, min_points_per_plane);
	FS_LOAD(c, s, radius_m);
	FS_LOAD(c, s, stem_model);
	FS_LOAD(c, s, stem_model_planar);
	FS_LOAD(c, s, stem_fit_radius_m);
	FS_LOAD(c, s, stem_fit_half_height_m);
	FS_LOAD(c, s, stem_min_points);
	FS_LOAD(c, s, stem_min_radius_m);
	FS_LOAD(c, s, stem_max_radius_m);
	FS_LOAD(c, s, stem_max_rmse_m);
	FS_LOAD(c, s, stem_min_arc_deg);
	const std::string where = core::configOrigin(c) + ": [" + s + "] ";
	if (!(cell_m > 0) || !(radius_m > 0) || !(planar_spacing_m >= 0) ||
	    !(edge_spacing_m >= 0) || !(coarse_voxel_m >= 0) ||
	    !(min_plane_spread_m >= 0))
		throw core::ConfigError(where +
		                        "cell_m and radius_m must be > 0; spacings, "
		                        "coarse_voxel_m and min_plane_spread_m >= 0");
	if (max_points_per_cell < 2 || max_points_per_voxel < 3 ||
	    min_points_per_plane < 3)
		throw core::ConfigError(
		    where +
		    "max_points_per_cell must be >= 2, "
		    "max_points_per_voxel and min_points_per_plane >= 3");
	if (!(stem_fit_radius_m > 0) || !(stem_fit_half_height_m > 0) ||
	    stem_min_points < 5 || !(stem_min_radius_m > 0) ||
	    !(stem_max_radius_m > stem_min_radius_m) || !(stem_max_rmse_m > 0) ||
	    !(stem_min_arc_deg >= 0 && stem_min_arc_deg <= 360))
		throw core::ConfigError(
		    where +
		    "stem_fit_radius_m, stem_fit_half_height_m, stem_min_radius_m "
		    "and stem_max_rmse_m must be > 0, stem_max_radius_m > "
		    "stem_min_radius_m, stem_min_points >= 5, stem_min_arc_deg in "
		    "0..360");
}

void LocalMapOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                       const std::string& s) const
{
	c.write(s, "cell_m", cell_m);
	c.write(s, "planar_spacing_m", planar_spacing_m);
	c.write(s, "edge_spacing_m", edge_spacing_m);
	c.write(s, "max_points_per_cell", max_points_per_cell);
	c.write(s, "min_plane_spread_m", min_plane_spread_m);
	c.write(s, "coarse_voxel_m", coarse_voxel_m);
	c.write(s, "max_points_per_voxel", max_points_per_voxel);
	c.write(s, "min_points_per_plane", min_points_per_plane);
	c.write(s, "radius_m", radius_m);
	c.write(s, "stem_model", stem_model);
	c.write(s, "stem_model_planar", stem_model_planar);
	c.write(s, "stem_fit_radius_m", stem_fit_radius_m);
	c.write(s, "stem_fit_half_height_m", stem_fit_half_height_m);
	c.write(s, "stem_min_points", stem_min_points);
	c.write(s, "stem_min_radius_m", stem_min_radius_m);
	c.write(s, "stem_max_radius_m", stem_max_radius_m);
	c.write(s, "stem_max_rmse_m", stem_max_rmse_m);
	c.write(s, "stem_min_arc_deg", stem_min_arc_deg);
}

namespace
{
/** Plane or line of a neighbourhood: mean and eigen-decomposition. */
struct Shape
{
	Eigen::Vector3d mean;
	Eigen::Vector3d ev;  // ascending
	Eigen::Matrix3d vecs;
};
Shape shapeOf(const std::vector<std::pair<float, Eigen::Vector3f>>& pts)
{
	Shape s;
	s.mean.setZero();
	for (const auto& pr : pts) s.mean += pr.second.cast<double>();
	s.mean /= pts.size();
	Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
	for (const auto& pr : pts)
	{
		const Eigen::Vector3d d = pr.second.cast<double>() - s.mean;
		C += d * d.transpose();
	}
	Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
	es.computeDirect(C / pts.size());
	s.ev = es.eigenvalues();
	s.vecs = es.eigenvectors();
	return s;
}
}  // namespace

namespace
{
/** Squared distances from x to the four points of a block (x0..x3 y0..y3
 * z0..z3) into d2; whether any is <= limit. */
inline bool blockWithin(const float* blk, const Eigen::Vector3f& x, float limit,
                        float d2[4])
{
#if defined(__SSE2__)
	const __m128 dx = _mm_sub_ps(_mm_loadu_ps(blk), _mm_set1_ps(x.x()));
	const __m128 dy = _mm_sub_ps(_mm_loadu_ps(blk + 4), _mm_set1_ps(x.y()));
	const __m128 dz = _mm_sub_ps(_mm_loadu_ps(blk + 8), _mm_set1_ps(x.z()));
	const __m128 d = _mm_add_ps(
	    _mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
	_mm_storeu_ps(d2, d);
	return _mm_movemask_ps(_mm_cmple_ps(d, _mm_set1_ps(limit))) != 0;
#else
	bool any = false;
	for (int l = 0; l < 4; l++)
	{
		const float dx = blk[l] - x.x(), dy = blk[4 + l] - x.y(),
		            dz = blk[8 + l] - x.z();
		d2[l] = dx * dx + dy * dy + dz * dz;
		any |= d2[l] <= limit;
	}
	return any;
#endif
}
}  // namespace

void LocalMap::PointCell::push(const Eigen::Vector3f& p)
{
	if (n % 4 == 0)
		blocks.insert(blocks.end(), 12, std::numeric_limits<float>::infinity());
	float* b = &blocks[(n / 4) * 12];
	const uint32_t l = n % 4;
	b[l] = p.x();
	b[4 + l] = p.y();
	b[8 + l] = p.z();
	n++;
}

bool LocalMap::PointCell::anyWithin(const Eigen::Vector3f& p, float d2) const
{
	if (!(d2 > 0)) return false;  // no spacing
	// Strictly closer than the spacing: the largest float below d2.
	const float limit = std::nextafter(d2, 0.f);
	float ignored[4];
	for (uint32_t b = 0; b < n; b += 4)
		if (blockWithin(&blocks[3 * b], p, limit, ignored)) return true;
	return false;
}

void LocalMap::addPoint(PointCell& c, float min_d2, const Eigen::Vector3f& p)
{
	if (static_cast<int>(c.n) >= o_.max_points_per_cell) return;
	if (!c.anyWithin(p, min_d2)) c.push(p);
}

namespace
{
/** How far ahead a bulk insertion asks for a cell's table slot, and for
 * the cell's points (by then the slot has arrived). */
constexpr size_t kAhead = 16;
constexpr size_t kBlocksAhead = 8;
}  // namespace

/** Asks the CPU to load the first points of cell k (if it exists): the
 * spacing test reads them right after the table slot, a second dependent
 * miss. (2000 handheld scans: 30 M spacing tests, 84 % of them find a kept
 * point within the spacing, after 5.2 blocks on average.) Only a hint. */
void LocalMap::prefetchPoints(const PointGrid& g, Key k)
{
	const PointCell* c = g.find(k);
	if (!c || c->blocks.empty()) return;
	const char* b = reinterpret_cast<const char*>(c->blocks.data());
	const size_t bytes =
	    std::min<size_t>(c->blocks.size() * sizeof(float), 256);
	for (size_t o = 0; o < bytes; o += 64) core::prefetchLine(b + o);
}

void LocalMap::insert(const std::vector<Eigen::Vector3f>& edges,
                      const std::vector<Eigen::Vector3f>& planar)
{
	dropStemFits();
	const float pd2 =
	    static_cast<float>(o_.planar_spacing_m * o_.planar_spacing_m);
	const float ed2 = static_cast<float>(o_.edge_spacing_m * o_.edge_spacing_m);
	const double sc = o_.coarse_voxel_m;
	std::vector<Key> touched;  // coarse voxels to refit
	// Keys first, then the insertions with the table slots kAhead points
	// further on prefetched: the probes missed the caches (half of this
	// function's time).
	thread_local std::vector<Key> cell_keys, coarse_keys;
	thread_local std::vector<uint32_t> index;
	cell_keys.clear();
	coarse_keys.clear();
	index.clear();
	for (uint32_t n = 0; n < planar.size(); n++)
	{
		const auto& p = planar[n];
		if (!p.allFinite()) continue;
		index.push_back(n);
		cell_keys.push_back(cellKey(p));
		if (sc > 0)
			coarse_keys.push_back(
			    key(static_cast<int64_t>(std::floor(p.x() / sc)),
			        static_cast<int64_t>(std::floor(p.y() / sc)),
			        static_cast<int64_t>(std::floor(p.z() / sc))));
	}
	for (size_t n = 0; n < index.size(); n++)
	{
		if (n + kAhead < index.size())
		{
			planar_.prefetch(cell_keys[n + kAhead]);
			if (sc > 0) coarse_.prefetch(coarse_keys[n + kAhead]);
		}
		if (n + kBlocksAhead < index.size())
			prefetchPoints(planar_, cell_keys[n + kBlocksAhead]);
		const auto& p = planar[index[n]];
		addPoint(planar_[cell_keys[n]], pd2, p);
		if (sc <= 0) continue;
		bool fresh = false;
		const Key kv = coarse_keys[n];
		auto& v = coarse_.tryEmplace(kv, &fresh);
		if (fresh)
			v.origin = Eigen::Vector3d(core::unpackCellIndex(kv, 0) * sc,
			                           core::unpackCellIndex(kv, 1) * sc,
			                           core::unpackCellIndex(kv, 2) * sc);
		if (v.n >= o_.max_points_per_voxel) continue;
		const Eigen::Vector3d q = p.cast<double>() - v.origin;
		v.sum += q;
		v.scatter.noalias() += q * q.transpose();
		if (v.n++ == v.fitted_n) touched.push_back(kv);
	}
	for (Key kv : touched)
	{
		PlaneVoxel& v = *coarse_.find(kv);
		refit(v);
		v.fitted_n = v.n;
	}
	cell_keys.clear();
	index.clear();
	for (uint32_t n = 0; n < edges.size(); n++)
		if (edges[n].allFinite())
			index.push_back(n), cell_keys.push_back(cellKey(edges[n]));
	for (size_t n = 0; n < index.size(); n++)
	{
		if (n + kAhead < index.size()) edges_.prefetch(cell_keys[n + kAhead]);
		if (n + kBlocksAhead < index.size())
			prefetchPoints(edges_, cell_keys[n + kBlocksAhead]);
		addPoint(edges_[cell_keys[n]], ed2, edges[index[n]]);
	}
}

void LocalMap::transform(const Eigen::Isometry3d& T)
{
	const Eigen::Isometry3f Tf = T.cast<float>();
	std::vector<Eigen::Vector3f> edges, planar;
	edges_.forEach(
	    [&](Key, const PointCell& c)
	    {
		    for (uint32_t i = 0; i < c.n; i++) edges.push_back(Tf * c.point(i));
	    });
	planar_.forEach(
	    [&](Key, const PointCell& c)
	    {
		    for (uint32_t i = 0; i < c.n; i++)
			    planar.push_back(Tf * c.point(i));
	    });
	clear();
	insert(edges, planar);
}

void LocalMap::prune(const Eigen::Vector3d& centre)
{
	dropStemFits();
	const double r2 = o_.radius_m * o_.radius_m;
	coarse_.eraseIf(
	    [&](Key, const PlaneVoxel& v)
	    { return (v.origin - centre).head<2>().squaredNorm() > r2; });
	for (auto* g : {&planar_, &edges_})
		g->eraseIf(
		    [&](Key, const PointCell& c)
		    {
			    return c.n == 0 || (c.point(0).cast<double>() - centre)
			                               .head<2>()
			                               .squaredNorm() > r2;
		    });
}

void LocalMap::refit(PlaneVoxel& v) const
{
	v.planar = false;
	if (v.n < o_.min_points_per_plane) return;
	const Eigen::Vector3d m = v.sum / v.n;
	const Eigen::Matrix3d C = v.scatter / v.n - m * m.transpose();
	Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
	es.computeDirect(C);
	const auto ev = es.eigenvalues();
	// A coarse voxel is a plane if its points spread over a tenth of it in
	// both in-plane directions.
	const double spread = 0.1 * o_.coarse_voxel_m;
	if (!(ev[0] <= plane_flatness_ * ev[1]) || ev[1] < spread * spread) return;
	v.normal = es.eigenvectors().col(0).normalized();
	v.mean = m + v.origin;
	v.planar = true;
}

bool LocalMap::coarsePlane(const Eigen::Vector3d& x, double gate, PlaneRow& out,
                           MatchReach& reach) const
{
	const double sp = o_.coarse_voxel_m;
	if (sp <= 0) return false;
	const int64_t i = static_cast<int64_t>(std::floor(x.x() / sp)),
	              j = static_cast<int64_t>(std::floor(x.y() / sp)),
	              k = static_cast<int64_t>(std::floor(x.z() / sp));
	static const int nb[7][3] = {{0, 0, 0}, {0, 0, -1}, {0, 0, 1}, {-1, 0, 0},
	                             {1, 0, 0}, {0, -1, 0}, {0, 1, 0}};
	double best = gate;
	bool found = false;
	for (const auto& d : nb)
	{
		const PlaneVoxel* it = coarse_.find(key(i + d[0], j + d[1], k + d[2]));
		if (!it) continue;
		const auto& v = *it;
		if (!v.planar) continue;
		const double e = std::abs(v.normal.dot(x - v.mean));
		// The point must project into the plane's extent, not onto its far
		// extension.
		if ((x - v.mean).squaredNorm() - e * e > sp * sp) continue;
		if (e < best)
		{
			best = e;
			out.n = v.normal;
			out.d = -v.normal.dot(v.mean);
			reach.gate_needed = e;
			found = true;
		}
	}
	return found;
}

void LocalMap::knn(const PointGrid& g, const Eigen::Vector3f& x, int k,
                   double extent,
                   std::vector<std::pair<float, Eigen::Vector3f>>& best) const
{
	best.clear();
	const double s = o_.cell_m;
	// Only the cells the sphere of radius `extent` touches (with cells at
	// least twice the extent: at most 8), nearest box first; a cell farther
	// than the current k-th neighbour is skipped, so most queries read only
	// their own cell. Cell indices as addPoint() computes them (double).
	int64_t c0[3];
	float lo_gap[3], hi_gap[3];  // distance from x to its cell's faces
	for (int a = 0; a < 3; a++)
	{
		const double f = std::floor(static_cast<double>(x[a]) / s);
		c0[a] = static_cast<int64_t>(f);
		lo_gap[a] = static_cast<float>(x[a] - f * s);
		hi_gap[a] = static_cast<float>((f + 1) * s - x[a]);
	}
	const float e = static_cast<float>(extent);
	const int reach = static_cast<int>(std::ceil(extent / s));
	struct Cell
	{
		float d2;
		int di[3];
	};
	thread_local std::vector<Cell> cells;
	cells.clear();
	for (int i = -reach; i <= reach; i++)
		for (int j = -reach; j <= reach; j++)
			for (int m = -reach; m <= reach; m++)
			{
				const int d[3] = {i, j, m};
				float d2 = 0;
				for (int a = 0; a < 3; a++)
				{
					// Gap from x to the box of the cell d[a] steps away.
					const float gap =
					    d[a] < 0   ? lo_gap[a] + (-d[a] - 1) * float(s)
					    : d[a] > 0 ? hi_gap[a] + (d[a] - 1) * float(s)
					               : 0.f;
					d2 += gap * gap;
				}
				if (d2 > e * e) continue;
				Cell c{d2, {i, j, m}};
				cells.push_back(c);
				for (size_t n = cells.size() - 1;
				     n > 0 && cells[n - 1].d2 > c.d2; n--)
					std::swap(cells[n], cells[n - 1]);
			}
	float worst = e * e;
	for (const Cell& c : cells)
	{
		if (c.d2 > worst) break;
		const PointCell* cell =
		    g.find(key(c0[0] + c.di[0], c0[1] + c.di[1], c0[2] + c.di[2]));
		if (!cell) continue;
		// Four distances at a time; the points within the current k-th
		// distance are then taken in storage order, as one at a time would.
		for (uint32_t b = 0; b < cell->n; b += 4)
		{
			float d2[4];
			if (!blockWithin(&cell->blocks[3 * b], x, worst, d2)) continue;
			for (uint32_t l = 0; l < 4; l++)
			{
				if (!(d2[l] <= worst)) continue;
				const Eigen::Vector3f p = cell->point(b + l);
				if (static_cast<int>(best.size()) < k)
					best.emplace_back(d2[l], p);
				else
					best.back() = {d2[l], p};
				for (size_t n = best.size() - 1;
				     n > 0 && best[n].first < best[n - 1].first; n--)
					std::swap(best[n], best[n - 1]);
				if (static_cast<int>(best.size()) == k)
					worst = best.back().first;
			}
		}
	}
}

namespace
{
/** A stem section: circle centre c (relative to the fit's centre, at its
 * height), lean l (centre moves by l per metre up), radius r. */
struct StemCircle
{
	Eigen::Vector2d c = Eigen::Vector2d::Zero(), l = Eigen::Vector2d::Zero();
	double r = 0;
};

/** Robust geometric fit of a leaning circle to points (x, y, height; relative
 * to the cell centre), accepted if it is a stem by the options' tests:
 * Kasa's algebraic circle as the start (walls, whose circle is metres wide,
 * stop there), then Gauss-Newton on the orthogonal distances with a Huber
 * weight (scale stem_max_rmse_m); inliers within three scales give the RMSE
 * and the arc. */
bool fitStemCircle(const std::vector<Eigen::Vector3d>& q,
                   const LocalMapOptions& o, StemCircle& f)
{
	const size_t n = q.size();
	if (n < 5) return false;
	Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
	Eigen::Vector3d b = Eigen::Vector3d::Zero();
	for (const auto& p : q)
	{
		const Eigen::Vector3d row(p.x(), p.y(), 1.0);
		const double z = -(p.x() * p.x() + p.y() * p.y());
		A.noalias() += row * row.transpose();
		b += z * row;
	}
	const Eigen::Vector3d s = A.ldlt().solve(b);
	f.c = Eigen::Vector2d(-0.5 * s[0], -0.5 * s[1]);
	const double r2 = f.c.squaredNorm() - s[2];
	if (!(r2 > 0) || !std::isfinite(r2)) return false;
	f.r = std::sqrt(r2);
	if (f.r > 2 * o.stem_max_radius_m) return false;
	f.l.setZero();
	// 5 parameters: c (2), l (2), r; a weak prior keeps the lean small
	// (a short band of points hardly sees it).
	constexpr double kLeanPrior = 1.0 / (0.1 * 0.1);
	const double huber = o.stem_max_rmse_m;
	for (int it = 0; it < 6; it++)
	{
		// The normal equations from sums over the points: J = -(u, z u, 1)
		// with u the unit radial direction, so H's blocks are the weighted
		// sums of u u^T, z u u^T, z^2 u u^T, u, z u and 1 (Eigen's rank
		// update of a 5x5 was not inlined: a tenth of a mapping run's CPU).
		double uu[3][3] = {}, su[2][2] = {}, sw = 0, eu[2][2] = {}, ew = 0;
		for (const auto& p : q)
		{
			const double z = p.z();
			const double dx = p.x() - f.c.x() - f.l.x() * z,
			             dy = p.y() - f.c.y() - f.l.y() * z;
			const double rho = std::sqrt(dx * dx + dy * dy);
			if (rho < 1e-9) continue;
			const double e = rho - f.r;
			const double w = std::abs(e) <= huber ? 1.0 : huber / std::abs(e);
			const double inv = 1.0 / rho, ux = dx * inv, uy = dy * inv;
			const double m[3] = {w * ux * ux, w * ux * uy, w * uy * uy};
			const double zp[3] = {1.0, z, z * z};
			for (int t = 0; t < 3; t++)
			{
				uu[t][0] += zp[t] * m[0];
				uu[t][1] += zp[t] * m[1];
				uu[t][2] += zp[t] * m[2];
			}
			su[0][0] += w * ux, su[0][1] += w * uy;
			su[1][0] += w * z * ux, su[1][1] += w * z * uy;
			sw += w;
			eu[0][0] += w * e * ux, eu[0][1] += w * e * uy;
			eu[1][0] += w * e * z * ux, eu[1][1] += w * e * z * uy;
			ew += w * e;
		}
		auto block = [](const double* v)
		{
			Eigen::Matrix2d M;
			M << v[0], v[1], v[1], v[2];
			return M;
		};
		Eigen::Matrix<double, 5, 5> H;
		H.block<2, 2>(0, 0) = block(uu[0]);
		H.block<2, 2>(0, 2) = H.block<2, 2>(2, 0) = block(uu[1]);
		H.block<2, 2>(2, 2) = block(uu[2]);
		H.block<2, 1>(0, 4) = H.block<1, 2>(4, 0).transpose() =
		    Eigen::Vector2d(su[0][0], su[0][1]);
		H.block<2, 1>(2, 4) = H.block<1, 2>(4, 2).transpose() =
		    Eigen::Vector2d(su[1][0], su[1][1]);
		H(4, 4) = sw;
		Eigen::Matrix<double, 5, 1> g;
		g << -eu[0][0], -eu[0][1], -eu[1][0], -eu[1][1], -ew;
		H(2, 2) += kLeanPrior, H(3, 3) += kLeanPrior;
		g.segment<2>(2) += kLeanPrior * f.l;
		const Eigen::Matrix<double, 5, 1> dx = H.ldlt().solve(-g);
		if (!dx.allFinite()) return false;
		f.c += dx.head<2>(), f.l += dx.segment<2>(2), f.r += dx[4];
		if (dx.head<2>().norm() < 1e-4 && std::abs(dx[4]) < 1e-4) break;
	}
	if (!(f.r >= o.stem_min_radius_m && f.r <= o.stem_max_radius_m))
		return false;
	double sq = 0;
	thread_local std::vector<Eigen::Vector2d> inlier_dirs;
	inlier_dirs.clear();
	for (const auto& p : q)
	{
		const Eigen::Vector2d d = p.head<2>() - f.c - f.l * p.z();
		const double e = d.norm() - f.r;
		if (std::abs(e) > 3 * huber) continue;
		sq += e * e;
		inlier_dirs.push_back(d);
	}
	const int inliers = static_cast<int>(inlier_dirs.size());
	if (inliers < o.stem_min_points || sq > inliers * huber * huber)
		return false;
	// The arc the inliers cover: 10 deg bins, 360 minus the longest run of
	// empty ones (a shrub's or a wall's points can fit a stem-sized circle
	// on a short arc).
	constexpr int kBins = 36;
	bool seen[kBins] = {};
	for (const auto& d : inlier_dirs)
	{
		const double a = std::atan2(d.y(), d.x()) + M_PI;  // 0..2 pi
		seen[std::min(kBins - 1, static_cast<int>(a * kBins / (2 * M_PI)))] =
		    true;
	}
	int run = 0, longest = 0;
	for (int i = 0; i < 2 * kBins; i++)
	{
		run = seen[i % kBins] ? 0 : run + 1;
		longest = std::max(longest, std::min(run, kBins));
	}
	return 360.0 * (kBins - longest) / kBins >= o.stem_min_arc_deg;
}
}  // namespace

LocalMap::StemCell LocalMap::fitStemAt(const Eigen::Vector3f& centre) const
{
	StemCell cell;
	cell.z0 = centre.z();
	const double R = o_.stem_fit_radius_m, hh = o_.stem_fit_half_height_m;
	const double s = o_.cell_m;
	thread_local std::vector<Eigen::Vector3d> q;
	q.clear();
	const float R2 = static_cast<float>(R * R);
	auto range = [&](double v, double e, int64_t& a, int64_t& b)
	{
		a = static_cast<int64_t>(std::floor((v - e) / s));
		b = static_cast<int64_t>(std::floor((v + e) / s));
	};
	int64_t i0, i1, j0, j1, k0, k1;
	range(centre.x(), R, i0, i1);
	range(centre.y(), R, j0, j1);
	range(centre.z(), hh, k0, k1);
	for (const PointGrid* g : {&planar_, &edges_})
		for (int64_t i = i0; i <= i1; i++)
			for (int64_t j = j0; j <= j1; j++)
				for (int64_t k = k0; k <= k1; k++)
				{
					const PointCell* c = g->find(key(i, j, k));
					if (!c) continue;
					for (uint32_t m = 0; m < c->n; m++)
					{
						const Eigen::Vector3f p = c->point(m);
						const float dz = p.z() - centre.z();
						if (std::abs(dz) > hh) continue;
						const Eigen::Vector2f d =
						    p.head<2>() - centre.head<2>();
						if (d.squaredNorm() > R2) continue;
						q.emplace_back(d.x(), d.y(), dz);
					}
				}
	if (static_cast<int>(q.size()) < o_.stem_min_points) return cell;
	StemCircle f;
	if (!fitStemCircle(q, o_, f)) return cell;
	cell.ok = true;
	cell.centre = f.c + centre.head<2>().cast<double>();
	cell.lean = f.l;
	cell.r = f.r;
	return cell;
}

bool LocalMap::stemRow(const Eigen::Vector3f& x, double gate, PlaneRow& out,
                       MatchReach& reach) const
{
	// Fits are shared by the queries in one small cell until the map
	// changes (insertions run between registrations, never during one). Two
	// threads asking for the same new cell both fit it, to the same result,
	// rather than one waiting.
	const double cs = kStemCellM, zs = kStemCellHeightM;
	const int64_t i = static_cast<int64_t>(std::floor(x.x() / cs)),
	              j = static_cast<int64_t>(std::floor(x.y() / cs)),
	              k = static_cast<int64_t>(std::floor(x.z() / zs));
	const Key kc = key(i, j, k);
	StemCell cell;
	bool cached = false;
	{
		std::lock_guard<std::mutex> lock(stems_->mutex);
		if (const StemCell* c = stems_->cells.find(kc))
			cell = *c, cached = true;
	}
	if (!cached)
	{
		cell = fitStemAt(Eigen::Vector3f(float((i + 0.5) * cs),
		                                 float((j + 0.5) * cs),
		                                 float((k + 0.5) * zs)));
		std::lock_guard<std::mutex> lock(stems_->mutex);
		stems_->cells[kc] = cell;
	}
	if (!cell.ok) return false;
	// The residual e(x) = |x_xy - c(x_z)| - r, with the centre moving with
	// the lean, linearised at x: its gradient (u, -u.lean) is the normal (a
	// leaning stem ties height to the horizontal distance).
	const Eigen::Vector2d c = cell.centre + cell.lean * (x.z() - cell.z0);
	const Eigen::Vector2d d = x.head<2>().cast<double>() - c;
	const double rho = d.norm();
	const double e = rho - cell.r;
	if (rho < 1e-6 || std::abs(e) > gate) return false;
	const Eigen::Vector2d u = d / rho;
	const Eigen::Vector3d g(u.x(), u.y(), -u.dot(cell.lean));
	const double gn = g.norm();
	out.n = g / gn;
	out.d = (e - g.dot(x.cast<double>())) / gn;
	reach.gate_needed = std::max(reach.gate_needed, std::abs(e));
	return true;
}

bool LocalMap::matchPlane(const Eigen::Vector3f& x, double gate,
                          const RegistrationOptions& o, PlaneRow& out,
                          MatchReach& reach) const
{
	thread_local std::vector<std::pair<float, Eigen::Vector3f>> best;
	knn(planar_, x, o.knn, o.max_neighbourhood_m, best);
	if (static_cast<int>(best.size()) == o.knn &&
	    best.front().first <= gate * gate)
	{
		const Shape s = shapeOf(best);
		if (s.ev[0] <= o.plane_flatness * s.ev[1] &&
		    s.ev[1] >= o_.min_plane_spread_m * o_.min_plane_spread_m &&
		    s.ev[1] >= o.min_plane_spread_ratio * s.ev[2])
		{
			// The normal from the k neighbours, the plane through the nearest
			// one: on a stem the neighbours' mean lies inside the curved
			// surface (by the sagitta, which side depends on the view) and
			// would bias the pose sideways.
			out.n = s.vecs.col(0).normalized();
			out.d = -out.n.dot(best.front().second.cast<double>());
			reach.gate_needed = std::sqrt(best.front().first);
			if (o_.stem_model && o_.stem_model_planar &&
			    std::abs(out.n.z()) < 0.5 && stemRow(x, gate, out, reach))
				return true;
			const double e = std::abs(out.n.dot(x.cast<double>()) + out.d);
			if (e <= gate)
			{
				reach.gate_needed = std::max(reach.gate_needed, e);
				return true;
			}
		}
	}
	return coarsePlane(x.cast<double>(), gate, out, reach);
}

bool LocalMap::matchLine(const Eigen::Vector3f& x, double gate,
                         const RegistrationOptions& o, PlaneRow& a, PlaneRow& b,
                         MatchReach& reach) const
{
	thread_local std::vector<std::pair<float, Eigen::Vector3f>> best;
	knn(edges_, x, o.edge_knn, o.max_neighbourhood_m, best);
	if (static_cast<int>(best.size()) < o.edge_knn ||
	    best.front().first > gate * gate)
		return false;
	const Shape s = shapeOf(best);
	if (s.ev[2] < o.line_ratio * s.ev[1]) return false;
	const Eigen::Vector3d dir = s.vecs.col(2).normalized();
	reach.gate_needed = std::sqrt(best.front().first);
	if (o_.stem_model && std::abs(dir.z()) > 0.8 && stemRow(x, gate, a, reach))
	{
		// One row: the distance to the stem's surface; the second carries
		// nothing.
		b.n.setZero();
		b.d = 0;
		return true;
	}
	lineToPlanes(s.mean, dir, a, b);
	return true;
}

}  // namespace forest_slam::odometry
