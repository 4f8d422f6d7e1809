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

double headingOf(const Eigen::Matrix3d& R)
{
	Eigen::Vector3d a = R.col(0);
	if (a.head<2>().norm() < 0.3) a = R.col(1);
	return std::atan2(a.y(), a.x());
}

namespace
{
/** Angle a moved by multiples of 2 pi to within pi of `ref`. */
double unwrapNear(double a, double ref)
{
	return ref + std::remainder(a - ref, 2 * M_PI);
}

/** Least-squares line through (t, y), evaluated at `at`. */
double lineAt(const std::vector<std::pair<double, double>>& ty, double at)
{
	double mt = 0, my = 0;
	for (const auto& [t, y] : ty) mt += t, my += y;
	mt /= ty.size();
	my /= ty.size();
	double stt = 0, sty = 0;
	for (const auto& [t, y] : ty)
		stt += (t - mt) * (t - mt), sty += (t - mt) * (y - my);
	return stt > 0 ? my + sty / stt * (at - mt) : my;
}
}  // namespace

std::optional<Eigen::Vector3d> meanVelocityStep(
    const std::deque<TrackPoint>& track, double window_s, double t0_s,
    double t1_s, double heading_t1)
{
	// The constrained poses of the last window before the last of them.
	const TrackPoint* last = nullptr;
	for (auto it = track.rbegin(); it != track.rend() && !last; ++it)
		if (it->constrained) last = &*it;
	if (!last) return std::nullopt;
	std::vector<std::pair<double, double>> th;
	const TrackPoint* first = last;
	for (const auto& q : track)
		if (q.constrained && q.t_s >= last->t_s - window_s &&
		    q.t_s <= last->t_s)
		{
			if (q.t_s < first->t_s) first = &q;
			th.emplace_back(q.t_s, q.heading_rad);
		}
	const double span = last->t_s - first->t_s;
	if (span < 0.5 * window_s) return std::nullopt;
	for (size_t i = 1; i < th.size(); i++)
		th[i].second = unwrapNear(th[i].second, th[i - 1].second);
	const double t_mid = 0.5 * (first->t_s + last->t_s);
	const double h_mid = lineAt(th, t_mid);
	const Eigen::Vector3d v_heading =
	    Eigen::AngleAxisd(-h_mid, Eigen::Vector3d::UnitZ()) *
	    ((last->p - first->p) / span);
	// Heading now: a line through the last window of the track (held poses
	// included: their heading is the IMU's) and the heading at t1.
	std::vector<std::pair<double, double>> now;
	for (const auto& q : track)
		if (q.t_s >= t0_s - window_s && q.t_s <= t0_s)
			now.emplace_back(q.t_s, q.heading_rad);
	now.emplace_back(t1_s, heading_t1);
	for (size_t i = 1; i < now.size(); i++)
		now[i].second = unwrapNear(now[i].second, now[i - 1].second);
	const double h = lineAt(now, 0.5 * (t0_s + t1_s));
	return Eigen::AngleAxisd(h, Eigen::Vector3d::UnitZ()) * v_heading *
	       (t1_s - t0_s);
}

}  // namespace forest_slam::odometry
