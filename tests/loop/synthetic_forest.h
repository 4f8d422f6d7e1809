#pragma once
// A synthetic stand for the loop tests: wavy ground and vertical stems,
// sampled as a lidar at a pose would see it (points within a range, in the
// sensor frame). Deterministic for a seed.
#include <Eigen/Geometry>

#include <cmath>
#include <random>
#include <vector>

namespace forest_slam::loop::test
{
struct Stem
{
	Eigen::Vector2d c;
	double r;
};

/** Stems at random (seeded) or on a regular grid (`rows` true: rows along
 * x, `spacing` apart, trees `spacing` apart along the rows). */
inline std::vector<Stem> makeStems(unsigned seed, double half_size,
                                   bool rows = false, double spacing = 3.0)
{
	std::vector<Stem> s;
	std::mt19937 rng(seed);
	std::uniform_real_distribution<double> u(-half_size, half_size),
	    rr(0.1, 0.25);
	if (rows)
	{
		for (double x = -half_size; x <= half_size; x += spacing)
			for (double y = -half_size; y <= half_size; y += spacing)
				s.push_back({{x, y + 0.5 * spacing}, 0.15});
		return s;
	}
	for (int i = 0; i < static_cast<int>(half_size * half_size * 0.32); i++)
		s.push_back({{u(rng), u(rng)}, rr(rng)});  // ~800 stems/ha
	return s;
}

inline double groundZ(double x, double y)
{
	return 0.3 * std::sin(0.15 * x) + 0.2 * std::cos(0.11 * y + 0.5 * x * 0.1);
}

/** Points seen from `pose` (sensor -> world) within `range`, sensor
 * frame: ground samples and stem surfaces, every `step` metres. */
inline std::vector<Eigen::Vector3f> sampleView(const std::vector<Stem>& stems,
                                               const Eigen::Isometry3d& pose,
                                               double range, double step,
                                               unsigned seed)
{
	std::vector<Eigen::Vector3f> out;
	std::mt19937 rng(seed);
	std::normal_distribution<double> noise(0, 0.01);
	const Eigen::Vector3d c = pose.translation();
	const Eigen::Isometry3d inv = pose.inverse();
	for (double x = c.x() - range; x <= c.x() + range; x += step)
		for (double y = c.y() - range; y <= c.y() + range; y += step)
		{
			if (std::hypot(x - c.x(), y - c.y()) > range) continue;
			const Eigen::Vector3d p(x, y, groundZ(x, y) + noise(rng));
			out.push_back((inv * p).cast<float>());
		}
	for (const auto& s : stems)
	{
		if ((s.c - c.head<2>()).norm() > range) continue;
		// The half of the stem facing the sensor.
		const double a0 = std::atan2(c.y() - s.c.y(), c.x() - s.c.x());
		for (double a = a0 - 1.4; a <= a0 + 1.4; a += step / s.r / 2)
			for (double z = 0; z < 4.0; z += step / 2)
			{
				const Eigen::Vector3d p(
				    s.c.x() + s.r * std::cos(a), s.c.y() + s.r * std::sin(a),
				    groundZ(s.c.x(), s.c.y()) + z + noise(rng));
				out.push_back((inv * p).cast<float>());
			}
	}
	return out;
}

inline Eigen::Isometry3d poseXYZYaw(double x, double y, double z,
                                    double yaw_deg)
{
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	T.linear() =
	    Eigen::AngleAxisd(yaw_deg * M_PI / 180, Eigen::Vector3d::UnitZ())
	        .toRotationMatrix();
	T.translation() = Eigen::Vector3d(x, y, z);
	return T;
}

}  // namespace forest_slam::loop::test
