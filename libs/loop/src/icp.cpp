#include <forest_slam/loop/icp.h>
#include <forest_slam/odometry/kdtree.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>

namespace forest_slam::loop
{
namespace
{
/** The least float above d2: a search bound that still finds a point at
 * exactly d2 (the gates keep a match at their distance). */
float justAbove(float d2)
{
	return std::nextafter(d2, std::numeric_limits<float>::infinity());
}
}  // namespace

IcpTarget::IcpTarget(NormalCloud cloud)
    : cloud_(std::move(cloud)), tree_(std::make_unique<odometry::KdTree>())
{
	tree_->build(cloud_.points);
}

IcpTarget::~IcpTarget() = default;

IcpResult IcpTarget::evaluate(const std::vector<Eigen::Vector3f>& source,
                              const Eigen::Isometry3d& T,
                              const IcpOptions& o) const
{
	IcpResult res;
	res.T = T;
	if (source.empty() || cloud_.points.size() < 10) return res;
	using Mat6 = Eigen::Matrix<double, 6, 6>;
	using Vec6 = Eigen::Matrix<double, 6, 1>;
	// Statistics at the final gate.
	const float gate2 =
	    static_cast<float>(o.final_distance_m * o.final_distance_m);
	Mat6 H = Mat6::Zero();
	double sse = 0;
	size_t n = 0;
	uint32_t j;
	float d2;
	for (const auto& ps : source)
	{
		const Eigen::Vector3d p = T * ps.cast<double>();
		if (!tree_->nearestBelow(p.cast<float>(), justAbove(gate2), j, d2))
			continue;
		const Eigen::Vector3d q = cloud_.points[j].cast<double>();
		const Eigen::Vector3d nrm = cloud_.normals[j].cast<double>();
		const double r = nrm.dot(p - q);
		if (std::abs(r) > 3 * o.kernel_m) continue;
		Vec6 J;
		J.head<3>() = p.cross(nrm);
		J.tail<3>() = nrm;
		H.noalias() += J * J.transpose();
		sse += r * r;
		n++;
	}
	res.matches = n;
	res.overlap = static_cast<double>(n) / source.size();
	res.rmse_m = n > 0 ? std::sqrt(sse / n) : 1e9;
	// Rotation rows are in radians times metres: scale them by a 10 m lever
	// so that both blocks compare (a yaw of 0.1 deg moves points 1.7 cm).
	Eigen::Matrix<double, 6, 1> s;
	s << 0.1, 0.1, 0.1, 1, 1, 1;
	const Mat6 Hs = s.asDiagonal() * H * s.asDiagonal();
	Eigen::SelfAdjointEigenSolver<Mat6> es(Hs);
	res.information_eigenvalues = es.eigenvalues();
	return res;
}

IcpResult IcpTarget::align(const std::vector<Eigen::Vector3f>& source,
                           const Eigen::Isometry3d& guess,
                           const IcpOptions& o) const
{
	IcpResult res;
	res.T = guess;
	if (source.empty() || cloud_.points.size() < 10) return res;
	// Each source point's match in the last iteration: the nearest point
	// now is at most as far as it, a bound that prunes most of the k-d
	// tree's branches (the same matches as an unbounded search; the
	// back-end's k-d tree searches were ~8 % of the CPU of the 60-minute
	// run).
	constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
	std::vector<uint32_t> last(source.size(), kNone);
	uint32_t j;
	float d2;
	const double c2 = o.kernel_m * o.kernel_m;
	using Mat6 = Eigen::Matrix<double, 6, 6>;
	using Vec6 = Eigen::Matrix<double, 6, 1>;
	// The gate shrinks linearly over the first half of the iterations. Once
	// the pose stops moving at a gate it goes to the final gate at once: a
	// well-seeded alignment used to take 25 iterations at least, most of
	// them sub-millimetre updates (robot, first 5000 scans: 7705 -> 6703
	// iterations over 194 alignments, the same 36 of 50 closures).
	const int shrink = std::max(1, o.iterations / 2);
	double a = 0;  // where the gate is, from start (0) to final (1)
	for (int it = 0; it < o.iterations; it++)
	{
		res.iterations = it + 1;
		const double gate =
		    o.start_distance_m + a * (o.final_distance_m - o.start_distance_m);
		const float gate2 = static_cast<float>(gate * gate);
		Mat6 H = Mat6::Zero();
		Vec6 g = Vec6::Zero();
		size_t n = 0;
		for (size_t s = 0; s < source.size(); s++)
		{
			const Eigen::Vector3d p = res.T * source[s].cast<double>();
			const Eigen::Vector3f pf = p.cast<float>();
			float bound = justAbove(gate2);
			if (last[s] != kNone)
				bound = std::min(
				    bound,
				    justAbove(1.00001f *
				              (cloud_.points[last[s]] - pf).squaredNorm()));
			if (!tree_->nearestBelow(pf, bound, j, d2)) continue;
			last[s] = j;
			const Eigen::Vector3d q = cloud_.points[j].cast<double>();
			const Eigen::Vector3d nrm = cloud_.normals[j].cast<double>();
			const double r = nrm.dot(p - q);
			// Perturbation on the left: p' = exp(w) p + v.
			Vec6 J;
			J.head<3>() = p.cross(nrm);
			J.tail<3>() = nrm;
			const double w = 1.0 / (1.0 + r * r / c2);
			H.noalias() += w * J * J.transpose();
			g.noalias() += w * J * r;
			n++;
		}
		if (n < 6) return res;
		const Vec6 dx = -H.ldlt().solve(g);
		if (!dx.allFinite()) return res;
		Eigen::Isometry3d D = Eigen::Isometry3d::Identity();
		const double ang = dx.head<3>().norm();
		if (ang > 1e-12)
			D.linear() =
			    Eigen::AngleAxisd(ang, dx.head<3>() / ang).toRotationMatrix();
		D.translation() = dx.tail<3>();
		res.T = D * res.T;
		res.T.linear() =
		    Eigen::Quaterniond(res.T.linear()).normalized().toRotationMatrix();
		const bool still = dx.tail<3>().norm() < 1e-3 && ang < 1e-4;
		if (a >= 1.0 && still)
		{
			res.converged = true;
			break;
		}
		a = still ? 1.0 : std::min(1.0, a + 1.0 / shrink);
	}
	const IcpResult st = evaluate(source, res.T, o);
	res.overlap = st.overlap;
	res.rmse_m = st.rmse_m;
	res.matches = st.matches;
	res.information_eigenvalues = st.information_eigenvalues;
	return res;
}

}  // namespace forest_slam::loop
