#include <forest_slam/loop/pose_graph.h>
#include <forest_slam/loop/relative_pose_cost.h>

#include <ceres/ceres.h>
#include <ceres/manifold.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace forest_slam::loop
{
Matrix6d sqrtInformation(double sigma_t_m, double sigma_r_rad)
{
	Matrix6d S = Matrix6d::Zero();
	for (int i = 0; i < 3; i++)
	{
		S(i, i) = 1.0 / sigma_t_m;
		S(i + 3, i + 3) = 1.0 / sigma_r_rad;
	}
	return S;
}

size_t PoseGraph::addNode(const Eigen::Isometry3d& initial)
{
	poses_.push_back(initial);
	return poses_.size() - 1;
}

namespace
{
/** Antenna position in ENU against a fix. */
struct GnssCost
{
	Eigen::Vector3d antenna, enu, sigma;
	template <typename T>
	bool operator()(const T* p, const T* q, const T* yaw, const T* t,
	                T* res) const
	{
		Eigen::Map<const Eigen::Matrix<T, 3, 1>> pn(p), tn(t);
		Eigen::Map<const Eigen::Quaternion<T>> qn(q);
		const Eigen::Matrix<T, 3, 1> a = qn * antenna.template cast<T>() + pn;
		const T c = ceres::cos(yaw[0]), s = ceres::sin(yaw[0]);
		const Eigen::Matrix<T, 3, 1> e(c * a.x() - s * a.y() + tn.x(),
		                               s * a.x() + c * a.y() + tn.y(),
		                               a.z() + tn.z());
		for (int i = 0; i < 3; i++) res[i] = (e[i] - T(enu[i])) / T(sigma[i]);
		return true;
	}
};
}  // namespace

bool PoseGraph::initEnu(double min_baseline_m)
{
	// A horizontal rigid fit (Kabsch in 2D) of the antenna positions onto
	// the fixes, once they span the baseline.
	std::vector<Eigen::Vector3d> a, b;
	for (const auto& g : gnss_)
		if (!g.outlier)
		{
			a.push_back(poses_[g.node] * g.antenna_in_node);
			b.push_back(g.enu);
		}
	if (a.size() < 3) return false;
	double span = 0;
	for (const auto& x : a) span = std::max(span, (x - a[0]).head<2>().norm());
	if (span < min_baseline_m) return false;
	Eigen::Vector3d ma = Eigen::Vector3d::Zero(), mb = ma;
	for (size_t i = 0; i < a.size(); i++)
	{
		ma += a[i];
		mb += b[i];
	}
	ma /= a.size();
	mb /= b.size();
	double sxx = 0, sxy = 0;
	for (size_t i = 0; i < a.size(); i++)
	{
		const Eigen::Vector2d u = (a[i] - ma).head<2>(),
		                      v = (b[i] - mb).head<2>();
		sxx += u.dot(v);
		sxy += u.x() * v.y() - u.y() * v.x();
	}
	enu_.yaw = std::atan2(sxy, sxx);
	enu_.t = mb - Eigen::AngleAxisd(enu_.yaw, Eigen::Vector3d::UnitZ()) * ma;
	have_enu_ = true;
	return true;
}

bool PoseGraph::solve(bool with_gnss)
{
	const size_t n = poses_.size();
	std::vector<std::array<double, 3>> P(n);
	std::vector<std::array<double, 4>> Q(n);
	for (size_t i = 0; i < n; i++)
	{
		Eigen::Map<Eigen::Vector3d>(P[i].data()) = poses_[i].translation();
		Eigen::Map<Eigen::Quaterniond>(Q[i].data()) =
		    Eigen::Quaterniond(poses_[i].linear()).normalized();
	}
	double yaw = enu_.yaw;
	std::array<double, 3> t{enu_.t.x(), enu_.t.y(), enu_.t.z()};

	ceres::Problem::Options po;
	po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
	ceres::Problem problem(po);
	ceres::EigenQuaternionManifold quat;
	for (size_t i = 0; i < n; i++)
	{
		problem.AddParameterBlock(P[i].data(), 3);
		problem.AddParameterBlock(Q[i].data(), 4, &quat);
	}
	for (const auto& f : factors_)
	{
		auto* cost = new RelativePoseCost(
		    f.T_ab.translation(),
		    Eigen::Quaterniond(f.T_ab.linear()).normalized(),
		    f.sqrt_information);
		problem.AddResidualBlock(
		    cost, f.robust ? new ceres::CauchyLoss(1.0) : nullptr,
		    P[f.a].data(), Q[f.a].data(), P[f.b].data(), Q[f.b].data());
	}
	bool any_gnss = false;
	if (with_gnss)
		for (const auto& g : gnss_)
		{
			if (g.outlier) continue;
			auto* cost =
			    new ceres::AutoDiffCostFunction<GnssCost, 3, 3, 4, 1, 3>(
			        new GnssCost{g.antenna_in_node, g.enu, g.sigma});
			problem.AddResidualBlock(cost, new ceres::CauchyLoss(2.0),
			                         P[g.node].data(), Q[g.node].data(), &yaw,
			                         t.data());
			any_gnss = true;
		}
	if (n > 0)
	{
		problem.SetParameterBlockConstant(P[0].data());
		problem.SetParameterBlockConstant(Q[0].data());
	}
	ceres::Solver::Options so;
	so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
	// Eigen's sparse Cholesky: on an 11-lap graph of 3900 keyframes (a
	// solve after each of its 394 closures) 34.7 s against 48.5 s with
	// SuiteSparse, the same poses to the micrometre (doc/backend.md "Pose
	// graph").
	if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::EIGEN_SPARSE))
		so.sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE;
	// (A first trust region of 1e8 instead of Ceres' 1e4, i.e. a
	// Gauss-Newton first step, took that graph's solves to 21.6 s and
	// 0.7 mm from the optimum instead of 6.2 mm, but the trajectories' ATE
	// rose by 0.4-1.6 mm in all three bench worlds. Not kept.)
	so.max_num_iterations = 50;
	so.num_threads = 1;
	so.logging_type = ceres::SILENT;
	ceres::Solver::Summary summary;
	ceres::Solve(so, &problem, &summary);
	if (!summary.IsSolutionUsable()) return false;
	for (size_t i = 0; i < n; i++)
	{
		Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
		T.translation() = Eigen::Map<const Eigen::Vector3d>(P[i].data());
		T.linear() = Eigen::Map<const Eigen::Quaterniond>(Q[i].data())
		                 .normalized()
		                 .toRotationMatrix();
		poses_[i] = T;
	}
	if (any_gnss)
	{
		enu_.yaw = yaw;
		enu_.t = Eigen::Vector3d(t[0], t[1], t[2]);
	}
	return true;
}

bool PoseGraph::optimize(double gnss_min_baseline_m, double gnss_gate_sigma)
{
	const bool gnss =
	    !gnss_.empty() && (have_enu_ || initEnu(gnss_min_baseline_m));
	if (!solve(gnss)) return false;
	if (!gnss) return true;
	// Outlier gate: a fix farther than the gate from the solution is dropped
	// and the graph solved again without it (a GNSS jump must not bend the
	// map; the Cauchy loss already limits its pull).
	bool dropped = false;
	for (auto& g : gnss_)
	{
		if (g.outlier) continue;
		const Eigen::Vector3d e =
		    enu_.apply(poses_[g.node] * g.antenna_in_node) - g.enu;
		if (e.cwiseQuotient(g.sigma).norm() > gnss_gate_sigma)
		{
			g.outlier = true;
			dropped = true;
		}
	}
	return dropped ? solve(true) : true;
}

}  // namespace forest_slam::loop
