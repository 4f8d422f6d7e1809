#include <forest_slam/core/config.h>
#include <forest_slam/core/parallel_for.h>
#include <forest_slam/odometry/feature_registration.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace forest_slam::odometry
{
void RegistrationOptions::loadFromConfigFile(
    const mrpt::config::CConfigFileBase& c, const std::string& s)
{
	FS_LOAD(c, s, outer_iterations);
	FS_LOAD(c, s, lm_iterations);
	FS_LOAD(c, s, threads);
	FS_LOAD(c, s, max_correspondence_m);
	FS_LOAD(c, s, min_correspondence_m);
	FS_LOAD(c, s, knn);
	FS_LOAD(c, s, edge_knn);
	FS_LOAD(c, s, max_neighbourhood_m);
	FS_LOAD(c, s, huber_m);
	FS_LOAD(c, s, plane_flatness);
	FS_LOAD(c, s, line_ratio);
	FS_LOAD(c, s, prior_translation_sigma_m);
	FS_LOAD(c, s, prior_rotation_sigma_deg);
	FS_LOAD(c, s, gravity_sigma_deg);
	FS_LOAD(c, s, rematch_distance_m);
	FS_LOAD(c, s, converged_translation_m);
	FS_LOAD(c, s, converged_rotation_rad);
	const std::string where = core::configOrigin(c) + ": [" + s + "] ";
	if (outer_iterations < 1 || lm_iterations < 1)
		throw core::ConfigError(where + "iteration counts must be >= 1");
	if (threads < 1 || threads > 64)
		throw core::ConfigError(where + "threads must be in [1, 64]");
	if (knn < 3 || edge_knn < 2)
		throw core::ConfigError(where + "knn must be >= 3 and edge_knn >= 2");
	if (!(min_correspondence_m > 0) ||
	    !(max_correspondence_m >= min_correspondence_m) || !(huber_m > 0))
		throw core::ConfigError(where +
		                        "need 0 < min_correspondence_m <= "
		                        "max_correspondence_m and huber_m > 0");
	if (!(rematch_distance_m >= 0) ||
	    !(rematch_distance_m < min_correspondence_m))
		throw core::ConfigError(
		    where + "rematch_distance_m must be in [0, min_correspondence_m)");
}

void RegistrationOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                           const std::string& s) const
{
	c.write(s, "outer_iterations", outer_iterations);
	c.write(s, "lm_iterations", lm_iterations);
	c.write(s, "threads", threads);
	c.write(s, "max_correspondence_m", max_correspondence_m);
	c.write(s, "min_correspondence_m", min_correspondence_m);
	c.write(s, "knn", knn);
	c.write(s, "edge_knn", edge_knn);
	c.write(s, "max_neighbourhood_m", max_neighbourhood_m);
	c.write(s, "huber_m", huber_m);
	c.write(s, "plane_flatness", plane_flatness);
	c.write(s, "line_ratio", line_ratio);
	c.write(s, "prior_translation_sigma_m", prior_translation_sigma_m);
	c.write(s, "prior_rotation_sigma_deg", prior_rotation_sigma_deg);
	c.write(s, "gravity_sigma_deg", gravity_sigma_deg);
	c.write(s, "rematch_distance_m", rematch_distance_m);
	c.write(s, "converged_translation_m", converged_translation_m);
	c.write(s, "converged_rotation_rad", converged_rotation_rad);
}

void lineToPlanes(const Eigen::Vector3d& a, const Eigen::Vector3d& dir,
                  PlaneRow& p, PlaneRow& q)
{
	const Eigen::Vector3d u = dir.unitOrthogonal();
	const Eigen::Vector3d v = dir.cross(u).normalized();
	p = {u, -u.dot(a)};
	q = {v, -v.dot(a)};
}

namespace
{
struct LocalFit
{
	Eigen::Vector3d mean;
	Eigen::Vector3d evals;  // ascending
	Eigen::Matrix3d evecs;
	double nearest = 0;  ///< distance of the nearest neighbour
};

bool fitNeighbourhood(const KdTree& tree, const Eigen::Vector3f& q, int k,
                      double gate, double extent, LocalFit& fit)
{
	thread_local std::vector<uint32_t> idx;
	thread_local std::vector<float> d2;
	if (tree.knn(q, k, idx, d2) < static_cast<size_t>(k)) return false;
	if (d2.front() > gate * gate || d2.back() > extent * extent) return false;
	fit.nearest = std::sqrt(d2.front());
	fit.mean.setZero();
	for (auto i : idx) fit.mean += tree.points()[i].cast<double>();
	fit.mean /= idx.size();
	Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
	for (auto i : idx)
	{
		const Eigen::Vector3d d = tree.points()[i].cast<double>() - fit.mean;
		C += d * d.transpose();
	}
	Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
	es.computeDirect(C / idx.size());
	fit.evals = es.eigenvalues();
	fit.evecs = es.eigenvectors();
	return true;
}
}  // namespace

bool FeatureTarget::matchPlane(const Eigen::Vector3f& x, double gate,
                               const RegistrationOptions& o, PlaneRow& out,
                               MatchReach& reach) const
{
	LocalFit fit;
	if (!fitNeighbourhood(planar, x, o.knn, gate, o.max_neighbourhood_m, fit))
		return false;
	if (fit.evals[0] > o.plane_flatness * fit.evals[1]) return false;
	out.n = fit.evecs.col(0);
	out.d = -out.n.dot(fit.mean);
	reach.gate_needed = fit.nearest;
	return true;
}

bool FeatureTarget::matchLine(const Eigen::Vector3f& x, double gate,
                              const RegistrationOptions& o, PlaneRow& a,
                              PlaneRow& b, MatchReach& reach) const
{
	LocalFit fit;
	if (!fitNeighbourhood(edges, x, o.edge_knn, gate, o.max_neighbourhood_m,
	                      fit))
		return false;
	if (fit.evals[2] < o.line_ratio * fit.evals[1]) return false;
	lineToPlanes(fit.mean, fit.evecs.col(2), a, b);
	reach.gate_needed = fit.nearest;
	return true;
}

namespace
{
/** A residual row: source point (sensor frame) and its plane (map frame). */
struct Row
{
	Eigen::Vector3d p;
	PlaneRow plane;
	double s = 0;  ///< firing fraction of the sweep (sweep twist only)
};

using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat12 = Eigen::Matrix<double, 12, 12>;
using Vec12 = Eigen::Matrix<double, 12, 1>;

Eigen::Matrix3d expSO3(const Eigen::Vector3d& w)
{
	const double a = w.norm();
	if (a < 1e-12) return Eigen::Matrix3d::Identity();
	return Eigen::AngleAxisd(a, w / a).toRotationMatrix();
}

Eigen::Vector3d logSO3(const Eigen::Matrix3d& R)
{
	const Eigen::AngleAxisd aa(R);
	return aa.axis() * aa.angle();
}

/** The state is (R, t); an update δ = (δθ, δt) rotates about the sensor's
 * own position: x' = exp(δθ)(x - t) + t + δt, R' = exp(δθ) R, t' = t + δt.
 * Rotating about the sensor (not the map origin) keeps rotation and
 * translation decoupled far from the origin. With the sweep twist (w, v)
 * (`sweep`), a source point p fired at fraction s is exp(s w) p + s v
 * first; its update is additive. */
struct Problem
{
	const std::vector<Row>& rows;
	const RegistrationOptions& o;
	const RegistrationPriors& priors;
	bool sweep = false;

	/** Cost (Huber) at (R, t, twist); with H/g, the weighted normal
	 * equations (12 parameters with the sweep twist, else the top-left 6). */
	double evaluate(const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
	                const Vec6& twist, Mat12* H, Vec12* g, Mat6* info = nullptr,
	                double* sq = nullptr) const
	{
		double cost = 0;
		const double h = o.huber_m;
		if (H) H->setZero(), g->setZero();
		// Without the sweep twist: the 6x6 system accumulated on its own
		// (as dense as before the twist existed: the hot loop of every scan).
		Mat6 H6 = Mat6::Zero();
		Vec6 g6 = Vec6::Zero();
		for (const auto& r : rows)
		{
			const Eigen::Vector3d p =
			    sweep ? Eigen::Vector3d(expSO3(r.s * twist.head<3>()) * r.p +
			                            r.s * twist.tail<3>())
			          : r.p;
			const Eigen::Vector3d x = R * p + t;
			const double e = r.plane.n.dot(x) + r.plane.d;
			const double ae = std::abs(e);
			cost += ae <= h ? 0.5 * e * e : h * (ae - 0.5 * h);
			if (sq) *sq += e * e;
			if (!H) continue;
			const double w = ae <= h ? 1.0 : h / ae;
			Vec6 J;
			J << (x - t).cross(r.plane.n), r.plane.n;
			if (sweep)
			{
				// d/dw: s (p_rot x R^T n) (small-angle), d/dv: s R^T n.
				const Eigen::Vector3d nb = R.transpose() * r.plane.n;
				const Eigen::Vector3d p_rot = p - r.s * twist.tail<3>();
				Vec12 J12;
				J12 << J, r.s * p_rot.cross(nb), r.s * nb;
				H->noalias() += w * J12 * J12.transpose();
				*g += w * e * J12;
			}
			else
			{
				H6.noalias() += w * J * J.transpose();
				g6 += w * e * J;
			}
			if (info) info->noalias() += J * J.transpose();
		}
		if (H && !sweep)
		{
			H->topLeftCorner<6, 6>() = H6;
			g->head<6>() = g6;
		}
		if (sweep)
		{
			const double iw = 1.0 / kSweepTwistSigmaRad,
			             iv = 1.0 / kSweepTwistSigmaM;
			const Eigen::Vector3d ew = twist.head<3>() * iw,
			                      ev = twist.tail<3>() * iv;
			cost += 0.5 * (ew.squaredNorm() + ev.squaredNorm());
			if (H)
			{
				H->block<3, 3>(6, 6) += iw * iw * Eigen::Matrix3d::Identity();
				H->block<3, 3>(9, 9) += iv * iv * Eigen::Matrix3d::Identity();
				g->segment<3>(6) += iw * ew;
				g->segment<3>(9) += iv * ev;
			}
		}
		if (priors.motion && o.prior_translation_sigma_m > 0 &&
		    o.prior_rotation_sigma_deg > 0)
		{
			const double it = 1.0 / o.prior_translation_sigma_m;
			const double ir = 1.0 / (o.prior_rotation_sigma_deg * M_PI / 180);
			const Eigen::Vector3d et = (t - priors.motion->translation()) * it;
			const Eigen::Vector3d er =
			    logSO3(R * priors.motion->linear().transpose()) * ir;
			cost += 0.5 * (et.squaredNorm() + er.squaredNorm());
			if (H)
			{
				H->block<3, 3>(0, 0) += ir * ir * Eigen::Matrix3d::Identity();
				H->block<3, 3>(3, 3) += it * it * Eigen::Matrix3d::Identity();
				g->segment<3>(0) += ir * er;
				g->segment<3>(3) += it * et;
			}
		}
		if (priors.up_in_source && o.gravity_sigma_deg > 0)
		{
			const double ig = 1.0 / (o.gravity_sigma_deg * M_PI / 180);
			const Eigen::Vector3d v = R * *priors.up_in_source;
			// Residual: the horizontal part of "up" seen in the map frame.
			const Eigen::Vector2d e = v.head<2>() * ig;
			cost += 0.5 * e.squaredNorm();
			if (H)
			{
				// d(exp(δθ) v)/dδθ = -[v]x; rows x and y.
				Eigen::Matrix<double, 2, 6> J =
				    Eigen::Matrix<double, 2, 6>::Zero();
				J(0, 1) = v.z();
				J(0, 2) = -v.y();
				J(1, 0) = -v.z();
				J(1, 2) = v.x();
				J *= ig;
				H->topLeftCorner<6, 6>().noalias() += J.transpose() * J;
				g->head<6>().noalias() += J.transpose() * e;
			}
		}
		return cost;
	}
};
}  // namespace

RegistrationResult registerFeatures(
    const RegistrationTarget& target,
    const std::vector<Eigen::Vector3f>& src_edges,
    const std::vector<Eigen::Vector3f>& src_planar,
    const Eigen::Isometry3d& initial, const RegistrationOptions& o,
    const RegistrationPriors& priors)
{
	// A six-parameter problem with a few thousand rows per scan: the normal
	// equations are formed directly (analytic Jacobians), which is an order
	// of magnitude cheaper than building a Ceres problem per correspondence
	// search on every scan; Ceres stays for the pose graph.
	RegistrationResult res;
	Eigen::Matrix3d R =
	    Eigen::Quaterniond(initial.linear()).normalized().toRotationMatrix();
	Eigen::Vector3d t = initial.translation();
	std::vector<Row> rows;
	rows.reserve(src_planar.size() + 2 * src_edges.size());
	// Per feature: its match, and where it was searched (map frame).
	std::vector<uint8_t> plane_ok(src_planar.size()), edge_ok(src_edges.size());
	std::vector<PlaneRow> plane_rows(src_planar.size()),
	    edge_rows(2 * src_edges.size());
	std::vector<Eigen::Vector3f> plane_at(src_planar.size()),
	    edge_at(src_edges.size());
	std::vector<MatchReach> plane_reach(src_planar.size()),
	    edge_reach(src_edges.size());
	bool searched = false;
	double lambda = 1e-4;
	const bool sweep = priors.edge_fraction && priors.planar_fraction &&
	                   priors.edge_fraction->size() == src_edges.size() &&
	                   priors.planar_fraction->size() == src_planar.size();
	Vec6 twist = Vec6::Zero();

	const int shrink_steps = std::max(1, o.outer_iterations / 2);
	for (int it = 0; it < o.outer_iterations; it++)
	{
		res.iterations = it + 1;
		const double a = std::min(1.0, static_cast<double>(it) / shrink_steps);
		const double gate =
		    o.max_correspondence_m *
		    std::pow(o.min_correspondence_m / o.max_correspondence_m, a);
		const Eigen::Isometry3f T =
		    (Eigen::Translation3d(t) * Eigen::Quaterniond(R)).cast<float>();
		// Matches in parallel, each into its own slot; the rows are then
		// assembled in feature order, so the result is the same for any
		// thread count.
		const int np_src = static_cast<int>(src_planar.size());
		const int ne_src = static_cast<int>(src_edges.size());
		// A feature that moved less than rematch_distance_m keeps its match
		// while the match passes the gate (the gate only shrinks: a search
		// that failed fails again).
		const float keep2 = searched ? static_cast<float>(o.rematch_distance_m *
		                                                  o.rematch_distance_m)
		                             : -1.f;
		searched = true;
		// Chunks of 32 features (~50 us of k-NN): the helper thread, woken
		// while the caller starts, still gets its share of ~1000 features.
		core::parallelFor(
		    size_t(np_src + ne_src), o.threads, 32,
		    [&](size_t i_)
		    {
			    const int i = static_cast<int>(i_);
			    if (i < np_src)
			    {
				    const Eigen::Vector3f x = T * src_planar[i];
				    if ((x - plane_at[i]).squaredNorm() < keep2 &&
				        (!plane_ok[i] || plane_reach[i].gate_needed <= gate))
					    return;
				    plane_at[i] = x;
				    plane_ok[i] = target.matchPlane(x, gate, o, plane_rows[i],
				                                    plane_reach[i]);
			    }
			    else
			    {
				    const int e = i - np_src;
				    const Eigen::Vector3f x = T * src_edges[e];
				    if ((x - edge_at[e]).squaredNorm() < keep2 &&
				        (!edge_ok[e] || edge_reach[e].gate_needed <= gate))
					    return;
				    edge_at[e] = x;
				    edge_ok[e] =
				        target.matchLine(x, gate, o, edge_rows[2 * e],
				                         edge_rows[2 * e + 1], edge_reach[e]);
			    }
		    });
		rows.clear();
		size_t ne = 0, np = 0;
		for (int i = 0; i < np_src; i++)
			if (plane_ok[i])
			{
				rows.push_back({src_planar[i].cast<double>(), plane_rows[i],
				                sweep ? (*priors.planar_fraction)[i] : 0.0});
				np++;
			}
		for (int i = 0; i < ne_src; i++)
			if (edge_ok[i])
			{
				const Eigen::Vector3d p = src_edges[i].cast<double>();
				const double fs = sweep ? (*priors.edge_fraction)[i] : 0.0;
				rows.push_back({p, edge_rows[2 * i], fs});
				rows.push_back({p, edge_rows[2 * i + 1], fs});
				ne++;
			}
		res.edge_matches = ne;
		res.planar_matches = np;
		double r2 = 0;
		for (const auto& r : rows) r2 += r.p.squaredNorm();
		res.lever_arm_m = std::sqrt(r2 / std::max<size_t>(1, rows.size()));
		if (ne + np < 6) break;  // not enough constraints: keep the guess

		const Problem prob{rows, o, priors, sweep};
		const Eigen::Matrix3d R_start = R;
		const Eigen::Vector3d t_start = t;
		Mat12 H;
		Mat6 info;
		Vec12 g;
		for (int k = 0; k < o.lm_iterations; k++)
		{
			info.setZero();
			const double cost = prob.evaluate(R, t, twist, &H, &g, &info);
			res.information = info;
			res.information_eigenvalues =
			    Eigen::SelfAdjointEigenSolver<Mat6>(info).eigenvalues();
			// Levenberg–Marquardt: damp, try, accept if the cost drops.
			bool accepted = false;
			for (int tries = 0; tries < 6 && !accepted; tries++)
			{
				Vec12 dx = Vec12::Zero();
				if (sweep)
				{
					Mat12 A = H;
					A.diagonal() += lambda * H.diagonal().cwiseMax(1e-9);
					dx = A.ldlt().solve(-g);
				}
				else
				{
					Mat6 A = H.topLeftCorner<6, 6>();
					A.diagonal() += lambda * A.diagonal().cwiseMax(1e-9);
					dx.head<6>() = A.ldlt().solve(-g.head<6>());
				}
				if (!dx.allFinite()) break;
				const Eigen::Matrix3d R_new = expSO3(dx.head<3>()) * R;
				const Eigen::Vector3d t_new = t + dx.segment<3>(3);
				const Vec6 twist_new = twist + dx.tail<6>();
				if (prob.evaluate(R_new, t_new, twist_new, nullptr, nullptr) <
				    cost)
				{
					R = R_new;
					t = t_new;
					twist = twist_new;
					lambda = std::max(1e-7, lambda * 0.3);
					accepted = true;
					if (dx.head<3>().norm() < 0.1 * o.converged_rotation_rad &&
					    dx.segment<3>(3).norm() <
					        0.1 * o.converged_translation_m)
						k = o.lm_iterations;  // converged for these matches
				}
				else
					lambda *= 10;
			}
			if (!accepted) break;
		}
		double sq = 0;
		prob.evaluate(R, t, twist, nullptr, nullptr, nullptr, &sq);
		res.rmse_m = std::sqrt(sq / std::max<size_t>(1, rows.size()));
		const double dt = (t - t_start).norm();
		const double dr = Eigen::AngleAxisd(R * R_start.transpose()).angle();
		if (a >= 1.0 && dt < o.converged_translation_m &&
		    dr < o.converged_rotation_rad)
		{
			res.converged = true;
			break;
		}
	}
	Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
	out.linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
	out.translation() = t;
	res.T = out;
	res.sweep_twist = twist;
	return res;
}

}  // namespace forest_slam::odometry
