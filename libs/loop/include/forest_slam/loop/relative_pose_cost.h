#pragma once
// The pose graph's relative-pose error (Ceres' pose_graph_3d example) in two
// forms: the templated functor (automatic derivatives; the reference the
// unit test checks against) and RelativePoseCost, the same residual with its
// Jacobians in closed form, which PoseGraph uses. Included by pose_graph.cpp
// and its test only (it pulls in Ceres).
#include <forest_slam/loop/pose_graph.h>

#include <ceres/manifold.h>
#include <ceres/sized_cost_function.h>

#include <Eigen/Geometry>

namespace forest_slam::loop
{
/** r = S [q_a^-1 (p_b - p_a) - p_ab; 2 vec(q_ab (q_a^-1 q_b)^-1)] over
 * (p_a, q_a, p_b, q_b); quaternions in Eigen's (x, y, z, w) order. */
struct RelativePoseError
{
	Eigen::Vector3d p_ab;
	Eigen::Quaterniond q_ab;
	Matrix6d sqrt_info;
	template <typename T>
	bool operator()(const T* pa, const T* qa, const T* pb, const T* qb,
	                T* res) const
	{
		Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_a(pa), p_b(pb);
		Eigen::Map<const Eigen::Quaternion<T>> q_a(qa), q_b(qb);
		const Eigen::Quaternion<T> q_a_inv = q_a.conjugate();
		const Eigen::Quaternion<T> q_est = q_a_inv * q_b;
		const Eigen::Matrix<T, 3, 1> p_est = q_a_inv * (p_b - p_a);
		const Eigen::Quaternion<T> dq =
		    q_ab.template cast<T>() * q_est.conjugate();
		Eigen::Map<Eigen::Matrix<T, 6, 1>> r(res);
		r.template head<3>() = p_est - p_ab.template cast<T>();
		r.template tail<3>() = T(2.0) * dq.vec();
		r.applyOnTheLeft(sqrt_info.template cast<T>());
		return true;
	}
};

/** RelativePoseError with analytic Jacobians, for parameter blocks
 * (p_a: 3, q_a: 4 on ceres::EigenQuaternionManifold, p_b: 3, q_b: 4).
 *
 * Why: automatic derivatives through the quaternion products were 29 % of
 * a solve (an 11-lap graph of 3900 keyframes, a solve after each of its
 * 394 closures: 25.2 s, 19.3 s with these; the poses the same to 1 µm).
 *
 * The quaternions' Jacobians are derived in the manifold's tangent space:
 * Ceres' Plus is q <- [cos|w|, sin|w| w/|w|] q, a rotation by 2w applied
 * on the left, so with d = p_b - p_a and A = q_ab q_b^-1 (dq = A q_a):
 *   d e_p / d w_a = 2 R_a^T [d]x,   d e_p / d w_b = 0,
 *   d e_q / d w_a column i = 2 vec(A [0, e_i] q_a),   d e_q / d w_b = -that.
 * Ceres multiplies the ambient (6 x 4) Jacobian by the manifold's
 * PlusJacobian P (4 x 3); P's columns are orthonormal at a unit quaternion,
 * so the ambient Jacobian J_w P^T gives back J_w exactly. */
class RelativePoseCost final : public ceres::SizedCostFunction<6, 3, 4, 3, 4>
{
   public:
	RelativePoseCost(const Eigen::Vector3d& p_ab,
	                 const Eigen::Quaterniond& q_ab, const Matrix6d& sqrt_info)
	    : p_ab_(p_ab), q_ab_(q_ab), S_(sqrt_info)
	{
	}

	bool Evaluate(double const* const* x, double* residuals,
	              double** jacobians) const override
	{
		const Eigen::Map<const Eigen::Vector3d> p_a(x[0]), p_b(x[2]);
		const Eigen::Map<const Eigen::Quaterniond> q_a(x[1]), q_b(x[3]);
		const Eigen::Quaterniond q_a_inv = q_a.conjugate();
		const Eigen::Vector3d d = p_b - p_a;
		const Eigen::Quaterniond A = q_ab_ * q_b.conjugate();
		Eigen::Matrix<double, 6, 1> e;
		e.head<3>() = q_a_inv * d - p_ab_;
		e.tail<3>() = 2.0 * (A * q_a).vec();
		Eigen::Map<Eigen::Matrix<double, 6, 1>>(residuals).noalias() = S_ * e;
		if (!jacobians) return true;

		using RowMajor6x3 = Eigen::Matrix<double, 6, 3, Eigen::RowMajor>;
		using RowMajor6x4 = Eigen::Matrix<double, 6, 4, Eigen::RowMajor>;
		const Eigen::Matrix3d RaT = q_a_inv.toRotationMatrix();
		Eigen::Matrix<double, 6, 3> Jwa;  // d e / d w_a
		Jwa.topRows<3>() = 2.0 * RaT * skew(d);
		for (int i = 0; i < 3; i++)
		{
			Eigen::Quaterniond u(0, 0, 0, 0);
			u.vec()[i] = 1;
			Jwa.block<3, 1>(3, i) = 2.0 * (A * u * q_a).vec();
		}
		if (jacobians[0])
			Eigen::Map<RowMajor6x3>(jacobians[0]).noalias() =
			    -S_.leftCols<3>() * RaT;
		if (jacobians[2])
			Eigen::Map<RowMajor6x3>(jacobians[2]).noalias() =
			    S_.leftCols<3>() * RaT;
		if (jacobians[1])
			Eigen::Map<RowMajor6x4>(jacobians[1]).noalias() =
			    (S_ * Jwa) * plusJacobian(x[1]).transpose();
		if (jacobians[3])
			Eigen::Map<RowMajor6x4>(jacobians[3]).noalias() =
			    (-S_.rightCols<3>() * Jwa.bottomRows<3>()) *
			    plusJacobian(x[3]).transpose();
		return true;
	}

   private:
	static Eigen::Matrix3d skew(const Eigen::Vector3d& v)
	{
		Eigen::Matrix3d m;
		m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
		return m;
	}
	static Eigen::Matrix<double, 4, 3> plusJacobian(const double* q)
	{
		Eigen::Matrix<double, 4, 3, Eigen::RowMajor> P;
		ceres::EigenQuaternionManifold().PlusJacobian(q, P.data());
		return P;
	}

	Eigen::Vector3d p_ab_;
	Eigen::Quaterniond q_ab_;
	Matrix6d S_;
};
}  // namespace forest_slam::loop
