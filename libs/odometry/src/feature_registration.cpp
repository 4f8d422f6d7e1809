#include <forest_slam/core/config.h>
#include <forest_slam/odometry/feature_registration.h>

#include <ceres/ceres.h>

#include <Eigen/Eigenvalues>
#include <cmath>

namespace forest_slam::odometry
{
void RegistrationOptions::loadFromConfigFile(
	const mrpt::config::CConfigFileBase& c, const std::string& s)
{
	FS_LOAD(c, s, outer_iterations);
	FS_LOAD(c, s, lm_iterations);
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
	FS_LOAD(c, s, converged_translation_m);
	FS_LOAD(c, s, converged_rotation_rad);
	const std::string where = core::configOrigin(c) + ": [" + s + "] ";
	if (outer_iterations < 1 || lm_iterations < 1)
		throw core::ConfigError(where + "iteration counts must be >= 1");
	if (knn < 3 || edge_knn < 2)
		throw core::ConfigError(where + "knn must be >= 3 and edge_knn >= 2");
	if (!(min_correspondence_m > 0) || !(max_correspondence_m >= min_correspondence_m) ||
		!(huber_m > 0))
		throw core::ConfigError(
			where + "need 0 < min_correspondence_m <= max_correspondence_m and huber_m > 0");
}

void RegistrationOptions::saveToConfigFile(
	mrpt::config::CConfigFileBase& c, const std::string& s) const
{
	c.write(s, "outer_iterations", outer_iterations);
	c.write(s, "lm_iterations", lm_iterations);
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
	c.write(s, "converged_translation_m", converged_translation_m);
	c.write(s, "converged_rotation_rad", converged_rotation_rad);
}

namespace
{
struct PointToPlane
{
	Eigen::Vector3d p, n;
	double d;  // plane: n.x + d = 0
	template <typename T>
	bool operator()(const T* q, const T* t, T* r) const
	{
		const Eigen::Map<const Eigen::Quaternion<T>> Q(q);
		const Eigen::Map<const Eigen::Matrix<T, 3, 1>> tr(t);
		const Eigen::Matrix<T, 3, 1> x = Q * p.cast<T>() + tr;
		r[0] = n.cast<T>().dot(x) + T(d);
		return true;
	}
};

struct PointToLine
{
	Eigen::Vector3d p, a, dir;	// line through a along unit dir
	template <typename T>
	bool operator()(const T* q, const T* t, T* r) const
	{
		const Eigen::Map<const Eigen::Quaternion<T>> Q(q);
		const Eigen::Map<const Eigen::Matrix<T, 3, 1>> tr(t);
		const Eigen::Matrix<T, 3, 1> x = Q * p.cast<T>() + tr;
		const Eigen::Matrix<T, 3, 1> e = (x - a.cast<T>()).cross(dir.cast<T>());
		r[0] = e[0];
		r[1] = e[1];
		r[2] = e[2];
		return true;
	}
};

/** Pose prior: (t - t0)/sigma_t and 2 vec(q0^-1 q)/sigma_r. */
struct PosePrior
{
	Eigen::Quaterniond q0;
	Eigen::Vector3d t0;
	double inv_sigma_t, inv_sigma_r;
	template <typename T>
	bool operator()(const T* q, const T* t, T* r) const
	{
		const Eigen::Map<const Eigen::Quaternion<T>> Q(q);
		const Eigen::Quaternion<T> d = q0.conjugate().cast<T>() * Q;
		const T sign = d.w() < T(0) ? T(-1) : T(1);
		for (int i = 0; i < 3; i++)
		{
			r[i] = (t[i] - T(t0[i])) * T(inv_sigma_t);
			r[3 + i] = T(2) * sign * d.vec()[i] * T(inv_sigma_r);
		}
		return true;
	}
};

struct LocalFit
{
	Eigen::Vector3d mean;
	Eigen::Vector3d evals;	// ascending
	Eigen::Matrix3d evecs;
};

bool fitNeighbourhood(const KdTree& tree, const Eigen::Vector3f& q, int k,
					  double gate, double extent, std::vector<uint32_t>& idx,
					  std::vector<float>& d2, LocalFit& fit)
{
	if (tree.knn(q, k, idx, d2) < static_cast<size_t>(k)) return false;
	if (d2.front() > gate * gate || d2.back() > extent * extent) return false;
	fit.mean.setZero();
	for (auto i : idx) fit.mean += tree.points()[i].cast<double>();
	fit.mean /= idx.size();
	Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
	for (auto i : idx)
	{
		const Eigen::Vector3d d = tree.points()[i].cast<double>() - fit.mean;
		C += d * d.transpose();
	}
	Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C / idx.size());
	fit.evals = es.eigenvalues();
	fit.evecs = es.eigenvectors();
	return true;
}
}  // namespace

RegistrationResult registerFeatures(
	const FeatureTarget& target, const std::vector<Eigen::Vector3f>& src_edges,
	const std::vector<Eigen::Vector3f>& src_planar,
	const Eigen::Isometry3d& initial, const RegistrationOptions& o,
	const Eigen::Isometry3d* prior)
{
	RegistrationResult res;
	Eigen::Quaterniond q(initial.linear());
	q.normalize();
	Eigen::Vector3d t = initial.translation();
	std::vector<uint32_t> idx;
	std::vector<float> d2;

	const int shrink_steps = std::max(1, o.outer_iterations / 2);
	for (int it = 0; it < o.outer_iterations; it++)
	{
		res.iterations = it + 1;
		const double a = std::min(1.0, static_cast<double>(it) / shrink_steps);
		const double gate = o.max_correspondence_m *
							std::pow(o.min_correspondence_m / o.max_correspondence_m, a);
		const Eigen::Isometry3f T = (Eigen::Translation3d(t) * q).cast<float>();
		ceres::Problem::Options po;
		po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
		po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
		ceres::Problem problem(po);
		ceres::HuberLoss loss(o.huber_m);
		ceres::EigenQuaternionManifold quat_manifold;
		double qa[4] = {q.x(), q.y(), q.z(), q.w()};
		double ta[3] = {t.x(), t.y(), t.z()};
		problem.AddParameterBlock(qa, 4, &quat_manifold);
		problem.AddParameterBlock(ta, 3);
		Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
		size_t ne = 0, np = 0;
		LocalFit fit;
		for (const auto& p : src_planar)
		{
			const Eigen::Vector3f x = T * p;
			if (!fitNeighbourhood(target.planar, x, o.knn, gate, o.max_neighbourhood_m, idx, d2, fit))
				continue;
			if (fit.evals[0] > o.plane_flatness * fit.evals[1]) continue;
			const Eigen::Vector3d n = fit.evecs.col(0);
			problem.AddResidualBlock(
				new ceres::AutoDiffCostFunction<PointToPlane, 1, 4, 3>(
					new PointToPlane{p.cast<double>(), n, -n.dot(fit.mean)}),
				&loss, qa, ta);
			Eigen::Matrix<double, 6, 1> J;
			J << x.cast<double>().cross(n), n;
			H += J * J.transpose();
			np++;
		}
		for (const auto& p : src_edges)
		{
			const Eigen::Vector3f x = T * p;
			if (!fitNeighbourhood(target.edges, x, o.edge_knn, gate, o.max_neighbourhood_m, idx, d2, fit))
				continue;
			if (fit.evals[2] < o.line_ratio * fit.evals[1]) continue;
			const Eigen::Vector3d dir = fit.evecs.col(2);
			problem.AddResidualBlock(
				new ceres::AutoDiffCostFunction<PointToLine, 3, 4, 3>(
					new PointToLine{p.cast<double>(), fit.mean, dir}),
				&loss, qa, ta);
			// Information of the two directions normal to the line.
			for (int c = 0; c < 2; c++)
			{
				const Eigen::Vector3d n = fit.evecs.col(c);
				Eigen::Matrix<double, 6, 1> J;
				J << x.cast<double>().cross(n), n;
				H += J * J.transpose();
			}
			ne++;
		}
		if (prior && o.prior_translation_sigma_m > 0 && o.prior_rotation_sigma_deg > 0)
			problem.AddResidualBlock(
				new ceres::AutoDiffCostFunction<PosePrior, 6, 4, 3>(new PosePrior{
					Eigen::Quaterniond(prior->linear()).normalized(), prior->translation(),
					1.0 / o.prior_translation_sigma_m,
					1.0 / (o.prior_rotation_sigma_deg * M_PI / 180)}),
				nullptr, qa, ta);
		res.edge_matches = ne;
		res.planar_matches = np;
		if (ne + np < 6) break;	 // not enough constraints: keep the guess
		ceres::Solver::Options so;
		so.linear_solver_type = ceres::DENSE_QR;
		so.max_num_iterations = o.lm_iterations;
		so.num_threads = 1;
		ceres::Solver::Summary summary;
		ceres::Solve(so, &problem, &summary);
		const Eigen::Quaterniond q_new(qa[3], qa[0], qa[1], qa[2]);
		const Eigen::Vector3d t_new(ta[0], ta[1], ta[2]);
		const double dt = (t_new - t).norm();
		const double dr = q_new.angularDistance(q);
		q = q_new.normalized();
		t = t_new;
		res.rmse_m = std::sqrt(2 * summary.final_cost / std::max<size_t>(1, ne * 3 + np));
		res.information_eigenvalues =
			Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>>(H).eigenvalues();
		if (a >= 1.0 && dt < o.converged_translation_m && dr < o.converged_rotation_rad)
		{
			res.converged = true;
			break;
		}
	}
	res.T = Eigen::Translation3d(t) * q;
	return res;
}

}  // namespace forest_slam::odometry
