#include <forest_slam/trees/circle_fit.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace forest_slam::trees
{
namespace
{
/** RANSAC samples drawn at least, however clean the first ones were. */
constexpr int kMinRansacIterations = 20;

enum class LmStep
{
	Improved,   ///< x moved, the cost dropped
	Converged,  ///< same, by a negligible step: stop iterating
	Stuck,      ///< ten dampings and no lower cost: stop iterating
	Failed      ///< the solve gave non-finite values
};
/** One Levenberg–Marquardt step of a circle fit on the normal equations
 * H dx = -g (x[2] is the radius and must stay positive): the damping grows
 * tenfold until the cost does not rise, and shrinks after a step taken. */
template <class Mat, class Vec, class Cost>
LmStep dampedStep(const Mat& H, const Vec& g, double& lambda, Vec& x,
                  const Cost& cost)
{
	const double c0 = cost(x);
	for (int tries = 0; tries < 10; tries++)
	{
		Mat Hd = H;
		Hd.diagonal() *= (1 + lambda);
		const Vec step = Hd.ldlt().solve(-g);
		if (!step.allFinite()) return LmStep::Failed;
		const Vec xn = x + step;
		if (!(xn[2] > 0))
		{
			lambda *= 10;
			continue;
		}
		if (cost(xn) <= c0)
		{
			x = xn;
			lambda = std::max(lambda / 10, 1e-9);
			return step.norm() < 1e-9 ? LmStep::Converged : LmStep::Improved;
		}
		lambda *= 10;
	}
	return LmStep::Stuck;
}

std::vector<double> residuals(const Points2D& p, const Circle& c)
{
	std::vector<double> r(p.size());
	for (size_t i = 0; i < p.size(); i++)
		r[i] = (p[i] - c.centre).norm() - c.radius_m;
	return r;
}

/** Median of |r| (upper median), in place of a copy of `r`. */
double medianAbs(const std::vector<double>& r, std::vector<double>& buf)
{
	if (r.empty()) return 0;
	buf.resize(r.size());
	for (size_t i = 0; i < r.size(); i++) buf[i] = std::abs(r[i]);
	const auto mid = buf.begin() + buf.size() / 2;
	std::nth_element(buf.begin(), mid, buf.end());
	return *mid;
}

double madScale(const std::vector<double>& r, double min_scale)
{
	std::vector<double> a;
	return std::max(1.4826 * medianAbs(r, a), min_scale);
}

// Tukey biweight with the usual 95 % efficiency constant.
constexpr double kTukeyC = 4.685;

double tukeyRho(double r, double s)
{
	const double c = kTukeyC * s, u = r / c;
	if (std::abs(u) >= 1) return c * c / 6;
	const double t = 1 - u * u;
	return c * c / 6 * (1 - t * t * t);
}

double tukeyWeight(double r, double s)
{
	const double u = r / (kTukeyC * s);
	if (std::abs(u) >= 1) return 0;
	const double t = 1 - u * u;
	return t * t;
}

}  // namespace

bool circleThrough3(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                    const Eigen::Vector2d& c, Circle& out)
{
	const Eigen::Vector2d ab = b - a, ac = c - a;
	const double d = 2 * (ab.x() * ac.y() - ab.y() * ac.x());
	if (std::abs(d) < 1e-12) return false;
	const double ab2 = ab.squaredNorm(), ac2 = ac.squaredNorm();
	const Eigen::Vector2d u((ac.y() * ab2 - ab.y() * ac2) / d,
	                        (ab.x() * ac2 - ac.x() * ab2) / d);
	out.centre = a + u;
	out.radius_m = u.norm();
	return true;
}

bool fitCircleKasa(const Points2D& p, Circle& out)
{
	if (p.size() < 3) return false;
	Eigen::Vector2d mean = Eigen::Vector2d::Zero();
	for (const auto& q : p) mean += q;
	mean /= double(p.size());
	// Centred coordinates keep the normal equations well conditioned.
	Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
	Eigen::Vector3d b = Eigen::Vector3d::Zero();
	for (const auto& q : p)
	{
		const Eigen::Vector2d d = q - mean;
		const Eigen::Vector3d row(d.x(), d.y(), 1.0);
		A += row * row.transpose();
		b -= row * d.squaredNorm();
	}
	const Eigen::Vector3d s = A.colPivHouseholderQr().solve(b);
	if (!s.allFinite()) return false;
	const Eigen::Vector2d c(-s.x() / 2, -s.y() / 2);
	const double r2 = c.squaredNorm() - s.z();
	if (!(r2 > 0) || !std::isfinite(r2)) return false;
	out.centre = mean + c;
	out.radius_m = std::sqrt(r2);
	return true;
}

bool refineCircleGeometric(const Points2D& p, Circle& c, double min_scale_m,
                           int max_iterations)
{
	if (p.size() < 3) return false;
	Eigen::Vector3d x(c.centre.x(), c.centre.y(), c.radius_m);
	double lambda = 1e-3;
	// Buffers kept across calls: the tree layer fits thousands of slice
	// clusters per column, and the allocations were a tenth of the fit.
	thread_local std::vector<double> r, dist, buf;
	r.resize(p.size());
	dist.resize(p.size());
	for (int it = 0; it < max_iterations; it++)
	{
		const Circle cur{{x[0], x[1]}, x[2]};
		for (size_t i = 0; i < p.size(); i++)
		{
			dist[i] = (p[i] - cur.centre).norm();
			r[i] = dist[i] - cur.radius_m;
		}
		const double s = std::max(1.4826 * medianAbs(r, buf), min_scale_m);
		double cost = 0;
		// The lower triangle of H (all the LDLT reads), summed in scalars:
		// the 3x3 outer products were a tenth of the fit.
		double hxx = 0, hyx = 0, hyy = 0, hrx = 0, hry = 0, hrr = 0;
		Eigen::Vector3d g = Eigen::Vector3d::Zero();
		for (size_t i = 0; i < p.size(); i++)
		{
			cost += tukeyRho(r[i], s);
			const double w = tukeyWeight(r[i], s);
			if (w == 0) continue;
			const Eigen::Vector2d d = p[i] - cur.centre;
			const double n = std::max(dist[i], 1e-12);
			const double jx = -d.x() / n, jy = -d.y() / n;
			const double wx = w * jx, wy = w * jy;
			hxx += wx * jx, hyx += wy * jx, hyy += wy * jy;
			hrx -= w * jx, hry -= w * jy, hrr += w;
			g += Eigen::Vector3d(wx * r[i], wy * r[i], -w * r[i]);
		}
		Eigen::Matrix3d H;
		H << hxx, hyx, hrx, hyx, hyy, hry, hrx, hry, hrr;
		// Levenberg–Marquardt step on the IRLS quadratic model (scale fixed).
		bool improved = false;
		for (int tries = 0; tries < 10 && !improved; tries++)
		{
			Eigen::Matrix3d Hd = H;
			Hd.diagonal() *= (1 + lambda);
			const Eigen::Vector3d step = Hd.ldlt().solve(-g);
			if (!step.allFinite()) return false;
			const Eigen::Vector3d xn = x + step;
			const Circle nc{{xn[0], xn[1]}, std::abs(xn[2])};
			double ncost = 0;
			for (const auto& q : p)
				ncost += tukeyRho((q - nc.centre).norm() - nc.radius_m, s);
			if (ncost <= cost)
			{
				const double dx = step.norm();
				x = xn;
				x[2] = std::abs(x[2]);
				lambda = std::max(lambda / 10, 1e-9);
				improved = true;
				if (dx < 1e-6) it = max_iterations;
			}
			else
				lambda *= 10;
		}
		if (!improved) break;
	}
	c = Circle{{x[0], x[1]}, x[2]};
	return x.allFinite() && x[2] > 0;
}

namespace
{
/** Distance t along the ray q + t·d (d unit) from the circle's near
 * intersection to q (q = surface + t·d, so t > 0 behind the surface) and its
 * derivatives by (cx, cy, r); false if the ray misses the circle. */
/** rayResidual's t only (the cost evaluations need no Jacobian). */
bool rayDistance(const Eigen::Vector2d& q, const Eigen::Vector2d& d,
                 const Circle& c, double& t)
{
	const Eigen::Vector2d a = q - c.centre;
	const double ad = a.dot(d);
	const double disc = ad * ad - a.squaredNorm() + c.radius_m * c.radius_m;
	if (disc < 0) return false;
	t = ad + std::sqrt(disc);
	// rayResidual's test of a grazing ray: |F_t| = 2 |u . d| = 2 sqrt(disc).
	return 2 * std::sqrt(disc) >= 1e-12;
}
bool rayResidual(const Eigen::Vector2d& q, const Eigen::Vector2d& d,
                 const Circle& c, double& t, Eigen::Vector3d& J)
{
	// |a - s d| = r with a = q - c, the intersection at q - s d: s² - 2 (a·d) s
	// + |a|² - r² = 0; the near surface is the smaller root.
	const Eigen::Vector2d a = q - c.centre;
	const double ad = a.dot(d);
	const double disc = ad * ad - a.squaredNorm() + c.radius_m * c.radius_m;
	if (disc < 0) return false;
	t = ad + std::sqrt(disc);  // q = (near surface point) + t·d
	// Implicit derivatives of F(t, c, r) = |a - t d|² - r² = 0.
	const Eigen::Vector2d u = a - t * d;  // surface point - centre
	const double Ft = -2 * u.dot(d);
	if (std::abs(Ft) < 1e-12) return false;
	const Eigen::Vector2d Fc = -2 * u;
	const double Fr = -2 * c.radius_m;
	J << -Fc.x() / Ft, -Fc.y() / Ft, -Fr / Ft;
	return true;
}
}  // namespace

bool refineCircleAlongRays(const Points2D& p, const Points2D& dir, Circle& c,
                           double min_scale_m, int max_iterations)
{
	RayFitOptions o;
	o.min_scale_m = min_scale_m;
	o.max_iterations = max_iterations;
	return refineCircleAlongRays(p, dir, c, o);
}

bool refineCircleAlongRays(const Points2D& p, const Points2D& dir, Circle& c,
                           const RayFitOptions& o, Eigen::Vector2d* drift)
{
	const size_t n = p.size();
	if (dir.size() != n || n < 3 || (o.times && o.times->size() != n))
		return false;
	// Apparent drift of the stem: its centre at time t is c + v_k (t - t̄_k)
	// in pass k (t̄_k its mean time), under a Gaussian prior on each v_k.
	const bool moving = o.times && o.drift_sigma_m_per_s > 0;
	std::vector<double> dt(n, 0.0);
	std::vector<int> pass(n, 0);
	int passes = 1;
	if (moving)
	{
		std::vector<size_t> order(n);
		for (size_t i = 0; i < n; i++) order[i] = i;
		std::sort(order.begin(), order.end(),
		          [&](size_t a, size_t b)
		          { return (*o.times)[a] < (*o.times)[b]; });
		for (size_t j = 1; j < n; j++)
		{
			if ((*o.times)[order[j]] - (*o.times)[order[j - 1]] > o.pass_gap_s)
				passes++;
			pass[order[j]] = passes - 1;
		}
		std::vector<double> tm(passes, 0.0), cnt(passes, 0.0);
		for (size_t i = 0; i < n; i++)
			tm[pass[i]] += (*o.times)[i], cnt[pass[i]] += 1;
		for (size_t i = 0; i < n; i++)
			dt[i] = (*o.times)[i] - tm[pass[i]] / cnt[pass[i]];
	}
	const double inv_sv2 =
	    moving ? 1 / (o.drift_sigma_m_per_s * o.drift_sigma_m_per_s) : 0;
	// x = (cx, cy, r, v_0x, v_0y, v_1x, ...).
	const int m = 3 + 2 * passes;
	Eigen::VectorXd x = Eigen::VectorXd::Zero(m);
	x.head<3>() << c.centre.x(), c.centre.y(), c.radius_m;
	auto at = [&](const Eigen::VectorXd& v, size_t i)
	{
		const int k = 3 + 2 * pass[i];
		return Circle{{v[0] + v[k] * dt[i], v[1] + v[k + 1] * dt[i]}, v[2]};
	};
	double lambda = 1e-3;
	std::vector<double> r(n);
	std::vector<char> hit(n);
	// Cost with a fixed scale; a missed ray costs the Tukey maximum; the
	// prior on the v_k in the same units (s² per unit of squared residual).
	auto cost = [&](const Eigen::VectorXd& v, double s)
	{
		double sum = 0;
		for (size_t i = 0; i < n; i++)
		{
			double t;
			sum += rayDistance(p[i], dir[i], at(v, i), t) ? tukeyRho(t, s)
			                                              : tukeyRho(1e9, s);
		}
		return sum + 0.5 * s * s * inv_sv2 * v.tail(m - 3).squaredNorm();
	};
	std::vector<double> hits;
	std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>> Js(
	    n);
	Eigen::MatrixXd H(m, m);
	Eigen::VectorXd g(m);
	std::vector<Eigen::Matrix<double, 5, 5>,
	            Eigen::aligned_allocator<Eigen::Matrix<double, 5, 5>>>
	    Hp(passes);
	std::vector<Eigen::Matrix<double, 5, 1>,
	            Eigen::aligned_allocator<Eigen::Matrix<double, 5, 1>>>
	    gp(passes);
	for (int it = 0; it < o.max_iterations; it++)
	{
		hits.clear();
		for (size_t i = 0; i < n; i++)
		{
			hit[i] = rayResidual(p[i], dir[i], at(x, i), r[i], Js[i]);
			if (hit[i]) hits.push_back(r[i]);
		}
		if (hits.size() < 3) return false;
		const double s = madScale(hits, o.min_scale_m);
		// A point has derivatives by (c, r) and its own pass's drift only:
		// summed per pass in fixed 5x5 blocks (indexing the dynamic H per
		// point was most of this loop), then placed.
		for (int k = 0; k < passes; k++) Hp[k].setZero(), gp[k].setZero();
		for (size_t i = 0; i < n; i++)
		{
			if (!hit[i]) continue;
			const double w = tukeyWeight(r[i], s);
			if (w == 0) continue;
			const Eigen::Vector3d& J = Js[i];
			Eigen::Matrix<double, 5, 1> Jf;
			Jf << J[0], J[1], J[2], J[0] * dt[i], J[1] * dt[i];
			Hp[pass[i]].noalias() += (w * Jf) * Jf.transpose();
			gp[pass[i]].noalias() += (w * r[i]) * Jf;
		}
		H.setZero();
		g.setZero();
		for (int k = 0; k < passes; k++)
		{
			const int v = 3 + 2 * k;
			H.topLeftCorner<3, 3>() += Hp[k].topLeftCorner<3, 3>();
			H.block<3, 2>(0, v) += Hp[k].topRightCorner<3, 2>();
			H.block<2, 3>(v, 0) += Hp[k].bottomLeftCorner<2, 3>();
			H.block<2, 2>(v, v) += Hp[k].bottomRightCorner<2, 2>();
			g.head<3>() += gp[k].head<3>();
			g.segment<2>(v) += gp[k].tail<2>();
		}
		// Prior on the v_k (and pinned at 0 when not estimated).
		const double prior = moving ? s * s * inv_sv2 : 1.0;
		for (int j = 3; j < m; j++)
		{
			H(j, j) += prior;
			g[j] += prior * x[j];
		}
		const LmStep st = dampedStep(H, g, lambda, x,
		                             [&](const auto& v) { return cost(v, s); });
		if (st == LmStep::Failed) return false;
		if (st == LmStep::Stuck) break;
		if (st == LmStep::Converged) it = o.max_iterations;
	}
	c = Circle{{x[0], x[1]}, x[2]};
	if (drift)
	{
		std::vector<int> count(passes, 0);
		for (size_t i = 0; i < n; i++) count[pass[i]]++;
		const int k =
		    int(std::max_element(count.begin(), count.end()) - count.begin());
		*drift = x.segment<2>(3 + 2 * k);
	}
	return x.allFinite() && x[2] > 0;
}

bool refineCircleSegments(const Points2D& p, const Points2D& dir,
                          const std::vector<uint32_t>& segment,
                          double shift_sigma_m, Circle& c, Points2D* shifts,
                          double min_scale_m, int max_iterations)
{
	const size_t n = p.size();
	if (dir.size() != n || segment.size() != n || n < 3 || !(shift_sigma_m > 0))
		return false;
	// Dense segment indices 0..G-1 (in order of first appearance).
	std::vector<uint32_t> ids(segment);
	std::sort(ids.begin(), ids.end());
	ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
	const size_t G = ids.size();
	std::vector<size_t> g_of(n);
	for (size_t i = 0; i < n; i++)
		g_of[i] = size_t(std::lower_bound(ids.begin(), ids.end(), segment[i]) -
		                 ids.begin());
	const int m = 3 + 2 * int(G);
	Eigen::VectorXd x = Eigen::VectorXd::Zero(m);
	x << c.centre.x(), c.centre.y(), c.radius_m, Eigen::VectorXd::Zero(2 * G);
	// Residual of point i: along its ray if known (and the ray hits the
	// segment's circle), else orthogonal; J by (cx, cy, r) (the shift of
	// its segment has the centre's derivatives). false: a missed ray.
	auto residual =
	    [&](const Eigen::VectorXd& v, size_t i, double& r, Eigen::Vector3d& J)
	{
		const size_t g = g_of[i];
		const Circle cg{{v[0] + v[3 + 2 * g], v[1] + v[4 + 2 * g]}, v[2]};
		if (dir[i].squaredNorm() > 0)
			return rayResidual(p[i], dir[i], cg, r, J);
		const Eigen::Vector2d d = p[i] - cg.centre;
		const double dn = std::max(d.norm(), 1e-12);
		r = dn - cg.radius_m;
		J << -d.x() / dn, -d.y() / dn, -1.0;
		return true;
	};
	const double inv_s2 = 1 / (shift_sigma_m * shift_sigma_m);
	// Cost at a fixed scale s: Tukey on the points (a missed ray costs the
	// maximum) plus the Gaussian prior on the shifts in the same units.
	auto cost = [&](const Eigen::VectorXd& v, double s)
	{
		double sum = 0, r;
		for (size_t i = 0; i < n; i++)
		{
			const size_t g = g_of[i];
			const Circle cg{{v[0] + v[3 + 2 * g], v[1] + v[4 + 2 * g]}, v[2]};
			bool hit = true;
			if (dir[i].squaredNorm() > 0)
				hit = rayDistance(p[i], dir[i], cg, r);
			else
				r = std::max((p[i] - cg.centre).norm(), 1e-12) - cg.radius_m;
			sum += hit ? tukeyRho(r, s) : tukeyRho(1e9, s);
		}
		return sum + 0.5 * s * s * inv_s2 * v.tail(2 * G).squaredNorm();
	};
	double lambda = 1e-3;
	std::vector<double> r(n);
	std::vector<char> ok(n);
	std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>> Js(
	    n);
	std::vector<Eigen::Matrix3d, Eigen::aligned_allocator<Eigen::Matrix3d>> Hs(
	    G);
	std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>> gs(
	    G);
	std::vector<double> good;
	for (int it = 0; it < max_iterations; it++)
	{
		good.clear();
		for (size_t i = 0; i < n; i++)
		{
			ok[i] = residual(x, i, r[i], Js[i]);
			if (ok[i]) good.push_back(r[i]);
		}
		if (good.size() < 3) return false;
		const double s = madScale(good, min_scale_m);
		// Parameters a point touches: cx, cy, r and its segment's shift,
		// whose derivatives are the centre's: summed per segment in fixed
		// 3x3 blocks, then placed (as in refineCircleAlongRays).
		for (size_t k = 0; k < G; k++) Hs[k].setZero(), gs[k].setZero();
		for (size_t i = 0; i < n; i++)
		{
			if (!ok[i]) continue;
			const double w = tukeyWeight(r[i], s);
			if (w == 0) continue;
			const Eigen::Vector3d& J = Js[i];
			Hs[g_of[i]].noalias() += (w * J) * J.transpose();
			gs[g_of[i]].noalias() += (w * r[i]) * J;
		}
		Eigen::MatrixXd H = Eigen::MatrixXd::Zero(m, m);
		Eigen::VectorXd g = Eigen::VectorXd::Zero(m);
		for (size_t k = 0; k < G; k++)
		{
			const int v = 3 + 2 * int(k);
			H.topLeftCorner<3, 3>() += Hs[k];
			H.block<3, 2>(0, v) += Hs[k].leftCols<2>();
			H.block<2, 3>(v, 0) += Hs[k].topRows<2>();
			H.block<2, 2>(v, v) += Hs[k].topLeftCorner<2, 2>();
			g.head<3>() += gs[k];
			g.segment<2>(v) += gs[k].head<2>();
		}
		const double prior = s * s * inv_s2;
		for (int k = 3; k < m; k++)
		{
			H(k, k) += prior;
			g[k] += prior * x[k];
		}
		const LmStep st = dampedStep(H, g, lambda, x,
		                             [&](const auto& v) { return cost(v, s); });
		if (st == LmStep::Failed) return false;
		if (st == LmStep::Stuck) break;
		if (st == LmStep::Converged) it = max_iterations;
	}
	if (!x.allFinite() || !(x[2] > 0)) return false;
	c = Circle{{x[0], x[1]}, x[2]};
	if (shifts)
	{
		shifts->assign(n, Eigen::Vector2d::Zero());
		for (size_t i = 0; i < n; i++)
			(*shifts)[i] = x.segment<2>(3 + 2 * g_of[i]);
	}
	return true;
}

double silhouetteRadius(const Points2D& p, const Points2D& dir, const Circle& c,
                        double reach_m, size_t min_points)
{
	double sum_u2 = 0;
	size_t n = 0;
	const double reach2 = (c.radius_m + reach_m) * (c.radius_m + reach_m);
	for (size_t i = 0; i < p.size() && i < dir.size(); i++)
	{
		const Eigen::Vector2d q = p[i] - c.centre;
		const Eigen::Vector2d& d = dir[i];
		if (d.squaredNorm() == 0 || q.squaredNorm() > reach2) continue;
		const double u = d.x() * q.y() - d.y() * q.x();  // d unit: d x q
		sum_u2 += u * u;
		n++;
	}
	if (n < std::max<size_t>(min_points, 1))
		return std::numeric_limits<double>::quiet_NaN();
	return std::sqrt(3 * sum_u2 / double(n));
}

double arcCoverageDeg(const Points2D& p, const Circle& c, double max_residual_m,
                      double bin_deg)
{
	const int nb = std::max(1, int(std::lround(360.0 / bin_deg)));
	std::vector<char> seen(nb, 0);
	for (const auto& q : p)
	{
		const Eigen::Vector2d d = q - c.centre;
		if (std::abs(d.norm() - c.radius_m) > max_residual_m) continue;
		double a = std::atan2(d.y(), d.x()) * 180 / M_PI;
		if (a < 0) a += 360;
		seen[std::min(nb - 1, int(a / (360.0 / nb)))] = 1;
	}
	return std::count(seen.begin(), seen.end(), 1) * (360.0 / nb);
}

int ransacIterationsNeeded(double inlier_share, int min_iterations,
                           int max_iterations)
{
	const double w3 = std::pow(std::clamp(inlier_share, 0.0, 1.0), 3);
	if (w3 >= 1) return std::min(min_iterations, max_iterations);
	if (w3 <= 0) return max_iterations;
	const double n = std::log(1 - 0.999) / std::log1p(-w3);
	return std::clamp(static_cast<int>(std::ceil(n)), min_iterations,
	                  max_iterations);
}

CircleFitResult fitCircleRobust(const Points2D& p, const CircleFitOptions& o)
{
	CircleFitResult res;
	if (p.size() < 3) return res;
	std::vector<Circle> starts;
	Circle k;
	if (fitCircleKasa(p, k)) starts.push_back(k);

	// RANSAC: the 3-point circle with the most points within ransac_inlier_m,
	// so that a branch stub or leaves cannot pull the start. It stops once
	// an all-inlier sample is likely to have been drawn: about 10 samples
	// for a clean stem, where a fixed count drew ransac_iterations (300).
	std::mt19937 rng(o.seed);
	std::uniform_int_distribution<size_t> pick(0, p.size() - 1);
	Circle best;
	size_t best_n = 0;
	int needed = o.ransac_iterations;
	for (int it = 0; it < needed; it++)
	{
		const size_t a = pick(rng), b = pick(rng), c = pick(rng);
		if (a == b || b == c || a == c) continue;
		Circle cand;
		if (!circleThrough3(p[a], p[b], p[c], cand)) continue;
		if (cand.radius_m < o.min_radius_m || cand.radius_m > o.max_radius_m)
			continue;
		// |d - r| <= t as r-t <= d <= r+t on squares: no square root.
		const double lo = std::max(0.0, cand.radius_m - o.ransac_inlier_m),
		             hi = cand.radius_m + o.ransac_inlier_m;
		const double lo2 = lo * lo, hi2 = hi * hi;
		size_t n = 0;
		for (const auto& q : p)
		{
			const double d2 = (q - cand.centre).squaredNorm();
			n += d2 >= lo2 && d2 <= hi2;
		}
		if (n > best_n)
		{
			best_n = n, best = cand;
			needed = ransacIterationsNeeded(double(n) / double(p.size()),
			                                kMinRansacIterations,
			                                o.ransac_iterations);
		}
	}
	if (best_n >= 3)
	{
		// Plain geometric LS on the consensus set gives a good start.
		Points2D in;
		for (const auto& q : p)
			if (std::abs((q - best.centre).norm() - best.radius_m) <=
			    o.ransac_inlier_m)
				in.push_back(q);
		Circle c = best;
		// The consensus set's circle first: it is the start nearest the
		// answer on a stem with stubs.
		if (fitCircleKasa(in, c)) starts.insert(starts.begin(), c);
		starts.push_back(best);
	}

	double best_cost = std::numeric_limits<double>::infinity();
	for (auto c : starts)
	{
		// A start within the RANSAC tolerance of the best refined circle so
		// far lies in its basin: refining it finds the same circle (the
		// refinements were most of the fit's time).
		if (res.ok &&
		    (c.centre - res.circle.centre).norm() <= o.ransac_inlier_m &&
		    std::abs(c.radius_m - res.circle.radius_m) <= o.ransac_inlier_m)
			continue;
		if (!refineCircleGeometric(p, c)) continue;
		if (c.radius_m < o.min_radius_m || c.radius_m > o.max_radius_m)
			continue;
		// Compare candidates under one common scale (the RANSAC tolerance).
		const double s = o.ransac_inlier_m / 2;
		double cost = 0;
		for (const auto& q : p)
			cost += tukeyRho((q - c.centre).norm() - c.radius_m, s);
		if (cost < best_cost) best_cost = cost, res.circle = c, res.ok = true;
	}
	if (!res.ok) return res;
	return evaluateCircle(p, res.circle, o);
}

namespace
{
/** fitSolidRing's score: ring points minus points inside the solid stem. */
double solidRingScore(const Points2D& p, const Circle& c, double band_m)
{
	double s = 0;
	for (const auto& q : p)
	{
		const double r = (q - c.centre).norm() - c.radius_m;
		if (std::abs(r) < band_m)
			s += 1 - (r / band_m) * (r / band_m);
		else if (r < 0)
			s -= 1;
	}
	return s;
}
}  // namespace

Circle fitSolidRing(const Points2D& p, const Circle& start, double band_m,
                    int iterations, unsigned seed)
{
	if (p.size() < 3 || !(band_m > 0)) return start;
	std::mt19937 rng(seed);
	std::uniform_int_distribution<size_t> pick(0, p.size() - 1);
	Circle best = start;
	double best_score = solidRingScore(p, start, band_m);
	for (int it = 0; it < iterations; it++)
	{
		Circle c;
		if (!circleThrough3(p[pick(rng)], p[pick(rng)], p[pick(rng)], c))
			continue;
		// Foliage only makes a ring larger, and the stem is where the
		// start is.
		if (c.radius_m > 1.05 * start.radius_m ||
		    c.radius_m < 0.4 * start.radius_m ||
		    (c.centre - start.centre).norm() > start.radius_m)
			continue;
		const double s = solidRingScore(p, c, band_m);
		if (s > best_score) best_score = s, best = c;
	}
	if (best_score <= solidRingScore(p, start, band_m)) return start;
	for (int round = 0; round < 5; round++)
	{
		Points2D ring;
		for (const auto& q : p)
			if (std::abs((q - best.centre).norm() - best.radius_m) < band_m)
				ring.push_back(q);
		Circle c = best;
		if (ring.size() < 10 || !fitCircleKasa(ring, c) ||
		    !refineCircleGeometric(ring, c))
			break;
		best = c;
	}
	return best;
}

CircleFitResult evaluateCircle(const Points2D& p, const Circle& c,
                               const CircleFitOptions& o)
{
	CircleFitResult res;
	res.ok = true;
	res.circle = c;
	const auto r = residuals(p, c);
	res.scale_m = madScale(r, 1e-6);
	double ss = 0;
	for (double e : r)
		if (std::abs(e) <= 3 * res.scale_m) ss += e * e, res.n_inliers++;
	res.rmse_m = res.n_inliers ? std::sqrt(ss / res.n_inliers) : 0;
	res.arc_coverage_deg = arcCoverageDeg(p, c, 3 * res.scale_m, o.arc_bin_deg);
	return res;
}

CircleFitResult checkAgainstReference(
    const Points2D& p, const CircleFitResult& f, const Circle& reference,
    double reference_arc_deg, const CircleFitOptions& o, size_t min_points)
{
	if (!f.ok) return f;
	// Arcs within a fixed gate: a wrong circle's residual scale is wide.
	const double gate = 2 * o.ransac_inlier_m;
	const double r = reference.radius_m;
	const double arc_f = arcCoverageDeg(p, f.circle, gate, o.arc_bin_deg);
	if (2 * arc_f >= reference_arc_deg ||
	    std::abs(f.circle.radius_m - r) <= 0.25 * r)
		return f;
	Points2D near;
	for (const auto& q : p)
		if (std::abs((q - reference.centre).norm() - r) <= 2 * gate)
			near.push_back(q);
	Circle c = reference;
	if (near.size() < min_points || !refineCircleGeometric(near, c) ||
	    c.radius_m < o.min_radius_m || c.radius_m > o.max_radius_m ||
	    arcCoverageDeg(p, c, gate, o.arc_bin_deg) < arc_f)
		return f;
	return evaluateCircle(near, c, o);
}

}  // namespace forest_slam::trees
