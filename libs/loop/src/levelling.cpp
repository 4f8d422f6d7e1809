#include <forest_slam/loop/levelling.h>

#include <Eigen/Cholesky>
#include <cmath>

namespace forest_slam::loop
{
namespace
{
using Vec5 = Eigen::Matrix<double, 5, 1>;
using Mat5 = Eigen::Matrix<double, 5, 5>;

/** Rows of keyframe k: m_xy = tilt + (R_k bias)_xy, unknowns (tilt_x,
 * tilt_y, bias_x, bias_y, bias_z). */
Eigen::Matrix<double, 2, 5> rowsOf(const Eigen::Matrix3d& R)
{
	Eigen::Matrix<double, 2, 5> A;
	A.leftCols<2>().setIdentity();
	A.rightCols<3>() = R.topRows<2>();
	return A;
}
}  // namespace

Levelling estimateLevelling(
    const std::vector<Eigen::Matrix3d>& R_map_keyframe,
    const std::vector<std::optional<Eigen::Vector3d>>& up_in_keyframe,
    const LevellingOptions& o)
{
	Levelling out;
	const size_t n = std::min(R_map_keyframe.size(), up_in_keyframe.size());
	std::vector<size_t> use;
	std::vector<Eigen::Vector2d> m(n);
	for (size_t k = 0; k < n; k++)
	{
		if (!up_in_keyframe[k] || !up_in_keyframe[k]->allFinite() ||
		    !(up_in_keyframe[k]->norm() > 0.5))
			continue;
		const Eigen::Vector3d up =
		    R_map_keyframe[k] * up_in_keyframe[k]->normalized();
		if (!(up.z() > 0.9)) continue;  // not "up" at all: a broken sample
		m[k] = up.head<2>();
		use.push_back(k);
	}
	if (use.size() < o.min_keyframes) return out;
	const double wm = 1.0 / o.up_sigma_rad, wb = 1.0 / o.bias_sigma_rad;
	Vec5 x = Vec5::Zero();
	double rms = 0;
	for (int round = 0; round < 2; round++)
	{
		Mat5 H = Mat5::Zero();
		Vec5 g = Vec5::Zero();
		H.bottomRightCorner<3, 3>() += wb * wb * Eigen::Matrix3d::Identity();
		std::vector<size_t> kept;
		for (size_t k : use)
		{
			const auto A = rowsOf(R_map_keyframe[k]);
			if (round > 0 && (A * x - m[k]).norm() > 3 * rms) continue;
			H.noalias() += wm * wm * A.transpose() * A;
			g.noalias() += wm * wm * A.transpose() * m[k];
			kept.push_back(k);
		}
		x = H.ldlt().solve(g);
		double sse = 0;
		for (size_t k : kept)
			sse += (rowsOf(R_map_keyframe[k]) * x - m[k]).squaredNorm();
		rms = std::sqrt(sse / (2.0 * kept.size()));
		out.used = kept.size();
		out.rejected = use.size() - kept.size();
	}
	if (!x.allFinite()) return out;
	// Gravity's up in the map frame; R turns it onto z.
	const Eigen::Vector3d g_up = Eigen::Vector3d(x[0], x[1], 1).normalized();
	out.R = Eigen::Quaterniond::FromTwoVectors(g_up, Eigen::Vector3d::UnitZ())
	            .toRotationMatrix();
	out.tilt_deg = std::acos(std::clamp(g_up.z(), -1.0, 1.0)) * 180 / M_PI;
	out.bias_deg = x.tail<3>() * 180 / M_PI;
	out.residual_rms_deg = rms * 180 / M_PI;
	out.ok = true;
	return out;
}

}  // namespace forest_slam::loop
