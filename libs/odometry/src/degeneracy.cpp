#include <forest_slam/odometry/degeneracy.h>

#include <forest_slam/core/trajectory.h>

#include <Eigen/Eigenvalues>
#include <cmath>

namespace forest_slam::odometry
{
Eigen::Matrix<double, 6, 6> scaledInformation(
    const Eigen::Matrix<double, 6, 6>& information, double lever_arm_m)
{
	// Parameters [L w, t]: info' = S^-1 info S^-1, S = diag(L, L, L, 1, 1, 1).
	const double L = lever_arm_m > 0 ? lever_arm_m : 1.0;
	Eigen::Matrix<double, 6, 1> s;
	s << 1 / L, 1 / L, 1 / L, 1, 1, 1;
	return s.asDiagonal() * information * s.asDiagonal();
}

Eigen::Isometry3d remapDegenerate(
    const Eigen::Isometry3d& predicted, const Eigen::Isometry3d& estimate,
    const Eigen::Matrix<double, 6, 6>& information, double lever_arm_m,
    double ratio, int* weak_directions)
{
	using Mat6 = Eigen::Matrix<double, 6, 6>;
	using Vec6 = Eigen::Matrix<double, 6, 1>;
	if (weak_directions) *weak_directions = 0;
	const double L = lever_arm_m > 0 ? lever_arm_m : 1.0;
	const Eigen::SelfAdjointEigenSolver<Mat6> es(
	    scaledInformation(information, L));
	const Vec6& ev = es.eigenvalues();  // ascending
	if (!(ev[5] > 0)) return estimate;
	Mat6 keep = Mat6::Zero();
	int weak = 0;
	for (int i = 0; i < 6; i++)
	{
		if (ev[i] >= ratio * ev[5])
			keep +=
			    es.eigenvectors().col(i) * es.eigenvectors().col(i).transpose();
		else
			weak++;
	}
	if (weak_directions) *weak_directions = weak;
	if (weak == 0) return estimate;
	// The update from the prediction in the registration's parameterisation:
	// R = exp(w) R_pred, t = t_pred + dt.
	Vec6 d;
	const Eigen::AngleAxisd aa(estimate.linear() *
	                           predicted.linear().transpose());
	d.head<3>() = L * aa.angle() * aa.axis();
	d.tail<3>() = estimate.translation() - predicted.translation();
	Vec6 kept = keep * d;
	kept.head<3>() /= L;
	Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
	const double angle = kept.head<3>().norm();
	const Eigen::Matrix3d dR =
	    angle > 0 ? Eigen::AngleAxisd(angle, kept.head<3>() / angle)
	                    .toRotationMatrix()
	              : Eigen::Matrix3d::Identity();
	out.linear() = dR * predicted.linear();
	out.translation() = predicted.translation() + kept.tail<3>();
	return out;
}

Eigen::Isometry3d predictAcrossGap(
    const Eigen::Isometry3d& velocity, double period_s, double t0_s,
    double t1_s, const std::function<Eigen::Matrix3d(double, double)>& rotation)
{
	const double dt = t1_s - t0_s;
	const int n = std::max(1, static_cast<int>(std::ceil(dt / period_s)));
	const double h = dt / n;
	Eigen::Isometry3d step = core::interpolateIsometry(
	    Eigen::Isometry3d::Identity(), velocity, h / period_s);
	Eigen::Isometry3d acc = Eigen::Isometry3d::Identity();
	for (int i = 0; i < n; i++)
	{
		step.linear() = rotation(t0_s + i * h, t0_s + (i + 1) * h);
		acc = acc * step;
	}
	return acc;
}

}  // namespace forest_slam::odometry
