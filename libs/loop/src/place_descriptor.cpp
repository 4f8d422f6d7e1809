#include <forest_slam/loop/place_descriptor.h>

#include <algorithm>
#include <cmath>

namespace forest_slam::loop
{
PlaceDescriptor::PlaceDescriptor(const std::vector<Eigen::Vector3f>& levelled,
                                 const PlaceDescriptorOptions& o)
{
	const int R = o.rings, S = o.sectors;
	Eigen::MatrixXf lo = Eigen::MatrixXf::Constant(R, S, 1e9f);
	Eigen::MatrixXf hi = Eigen::MatrixXf::Constant(R, S, -1e9f);
	const float rmax = static_cast<float>(o.radius_m);
	for (const auto& p : levelled)
	{
		const float r = std::hypot(p.x(), p.y());
		if (!(r < rmax) || !p.allFinite()) continue;
		const int ring = std::min(R - 1, static_cast<int>(r / rmax * R));
		const float a = std::atan2(p.y(), p.x());  // [-pi, pi]
		int s = static_cast<int>(std::floor((a + M_PI) / (2 * M_PI) * S));
		s = ((s % S) + S) % S;
		lo(ring, s) = std::min(lo(ring, s), p.z());
		hi(ring, s) = std::max(hi(ring, s), p.z());
	}
	cells_ = Eigen::MatrixXf::Zero(R, S);
	size_t occupied = 0;
	for (int i = 0; i < R; i++)
		for (int j = 0; j < S; j++)
			if (hi(i, j) >= lo(i, j))
			{
				// A seen cell is never 0 (ground alone: 0.1 + its slope).
				cells_(i, j) = 0.1f + (hi(i, j) - lo(i, j));
				occupied++;
			}
	ring_key_ = cells_.rowwise().mean();
	occupancy_ = static_cast<double>(occupied) / (R * S);
}

DescriptorMatch matchDescriptors(const PlaceDescriptor& a,
                                 const PlaceDescriptor& b)
{
	DescriptorMatch m;
	const int S = a.sectors();
	if (a.empty() || b.empty() || S != b.sectors() || a.rings() != b.rings())
		return m;
	// Unit columns (0 where a sector saw nothing).
	auto unit = [](const Eigen::MatrixXf& c)
	{
		Eigen::MatrixXf u = c;
		for (int j = 0; j < c.cols(); j++)
		{
			const float n = c.col(j).norm();
			if (n > 0) u.col(j) /= n;
		}
		return u;
	};
	const Eigen::MatrixXf ua = unit(a.cells()), ub = unit(b.cells());
	// Similarities of every column pair, then the circular shifts.
	const Eigen::MatrixXf sim = ua.transpose() * ub;  // S x S
	std::vector<bool> va(S), vb(S);
	for (int j = 0; j < S; j++)
	{
		va[j] = a.cells().col(j).squaredNorm() > 0;
		vb[j] = b.cells().col(j).squaredNorm() > 0;
	}
	std::vector<double> d(S, 1.0);
	for (int k = 0; k < S; k++)
	{
		double sum = 0;
		int n = 0;
		for (int s = 0; s < S; s++)
		{
			const int t = (s + k) % S;
			if (!va[t] || !vb[s]) continue;
			sum += sim(t, s);
			n++;
		}
		// Too few common sectors to say anything.
		if (4 * n >= S) d[k] = 1.0 - sum / n;
	}
	int best = 0;
	for (int k = 1; k < S; k++)
		if (d[k] < d[best]) best = k;
	const double dm = d[(best + S - 1) % S], dp = d[(best + 1) % S];
	const double den = dm - 2 * d[best] + dp;
	const double off = den > 1e-12 ? 0.5 * (dm - dp) / den : 0.0;
	m.distance = d[best];
	double yaw = (best + std::clamp(off, -0.5, 0.5)) * 2 * M_PI / S;
	if (yaw > M_PI) yaw -= 2 * M_PI;
	m.yaw_rad = yaw;
	return m;
}

double yawOf(const Eigen::Matrix3d& R)
{
	return std::atan2(R(1, 0), R(0, 0));
}

Eigen::Matrix3d levellingRotation(const Eigen::Matrix3d& R)
{
	return Eigen::AngleAxisd(-yawOf(R), Eigen::Vector3d::UnitZ()) * R;
}

}  // namespace forest_slam::loop
