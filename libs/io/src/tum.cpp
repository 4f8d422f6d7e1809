#include <forest_slam/core/atomic_file.h>
#include <forest_slam/io/tum.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace forest_slam::io
{
core::Trajectory readTum(const std::string& path)
{
	std::ifstream f(path);
	if (!f) throw std::runtime_error("cannot open trajectory '" + path + "'");
	core::Trajectory traj;
	std::string line;
	size_t lineno = 0;
	while (std::getline(f, line))
	{
		lineno++;
		const auto b = line.find_first_not_of(" \t\r");
		if (b == std::string::npos || line[b] == '#') continue;
		std::istringstream is(line);
		double v[8];
		for (int i = 0; i < 8; i++)
			if (!(is >> v[i]))
				throw std::runtime_error(
					path + ":" + std::to_string(lineno) +
					": expected 8 numbers 't x y z qx qy qz qw'");
		for (double x : v)
			if (!std::isfinite(x))
				throw std::runtime_error(
					path + ":" + std::to_string(lineno) + ": non-finite value");
		core::StampedPose p;
		p.t_s = v[0];
		Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
		if (std::abs(q.norm() - 1.0) > 1e-3)
			throw std::runtime_error(
				path + ":" + std::to_string(lineno) +
				": quaternion is not unit length");
		q.normalize();
		p.pose.linear() = q.toRotationMatrix();
		p.pose.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
		if (!traj.empty() && p.t_s < traj.back().t_s)
			throw std::runtime_error(
				path + ":" + std::to_string(lineno) + ": time goes backwards");
		traj.push_back(p);
	}
	return traj;
}

void writeTum(const std::string& path, const core::Trajectory& traj)
{
	core::writeFileAtomically(path, [&](std::ostream& os) {
		os << "# timestamp tx ty tz qx qy qz qw\n";
		char buf[256];
		for (const auto& p : traj)
		{
			const Eigen::Quaterniond q(p.pose.linear());
			const auto& t = p.pose.translation();
			std::snprintf(buf, sizeof(buf),
						  "%.9f %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n", p.t_s,
						  t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
			os << buf;
		}
	});
}

void writeKitti(const std::string& path, const core::Trajectory& traj)
{
	core::writeFileAtomically(path, [&](std::ostream& os) {
		char buf[320];
		for (const auto& p : traj)
		{
			const auto& m = p.pose.matrix();
			std::snprintf(buf, sizeof(buf),
						  "%.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e "
						  "%.9e %.9e\n",
						  m(0, 0), m(0, 1), m(0, 2), m(0, 3), m(1, 0), m(1, 1),
						  m(1, 2), m(1, 3), m(2, 0), m(2, 1), m(2, 2), m(2, 3));
			os << buf;
		}
	});
}

}  // namespace forest_slam::io
