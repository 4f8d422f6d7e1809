#include <forest_slam/sim/body_trajectory.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace forest_slam::sim
{
Eigen::Matrix3d rotationYPR(double yaw, double pitch, double roll)
{
	const double cy = std::cos(yaw), sy = std::sin(yaw);
	const double cp = std::cos(pitch), sp = std::sin(pitch);
	const double cr = std::cos(roll), sr = std::sin(roll);
	Eigen::Matrix3d R;
	R << cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr,  //
	    sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr,   //
	    -sp, cp * sr, cp * cr;
	return R;
}

BodyTrajectory::BodyTrajectory(double t0, double dt, std::vector<Sample> ctrl)
    : t0_(t0), dt_(dt), ctrl_(std::move(ctrl))
{
	if (ctrl_.size() < 4 || !(dt > 0))
		throw std::invalid_argument("BodyTrajectory: need >= 4 control points");
}

void BodyTrajectory::channels(double t, Sample& val, Sample* d1,
                              Sample* d2) const
{
	const int n_seg = static_cast<int>(ctrl_.size()) - 3;
	double f = (t - t0_) / dt_;
	f = std::clamp(f, 0.0, static_cast<double>(n_seg));
	int i = static_cast<int>(std::floor(f));
	if (i >= n_seg) i = n_seg - 1;
	const double u = f - i, u2 = u * u, u3 = u2 * u, w = 1 - u;
	const double b[4] = {w * w * w / 6, (3 * u3 - 6 * u2 + 4) / 6,
	                     (-3 * u3 + 3 * u2 + 3 * u + 1) / 6, u3 / 6};
	const double db[4] = {-0.5 * w * w, 1.5 * u2 - 2 * u, -1.5 * u2 + u + 0.5,
	                      0.5 * u2};
	const double ddb[4] = {w, 3 * u - 2, -3 * u + 1, u};
	const double inv = 1.0 / dt_, inv2 = inv * inv;
	for (int c = 0; c < 6; c++)
	{
		const double p0 = ctrl_[i][c];
		if (ctrl_[i + 1][c] == p0 && ctrl_[i + 2][c] == p0 &&
		    ctrl_[i + 3][c] == p0)
		{
			// At rest: exactly the control value (the weights' sum is 1
			// only up to rounding), exactly zero derivatives.
			val[c] = p0;
			if (d1) (*d1)[c] = 0;
			if (d2) (*d2)[c] = 0;
			continue;
		}
		double v = 0, v1 = 0, v2 = 0;
		for (int j = 0; j < 4; j++)
		{
			const double p = ctrl_[i + j][c];
			v += b[j] * p;
			v1 += db[j] * p;
			v2 += ddb[j] * p;
		}
		val[c] = v;
		if (d1) (*d1)[c] = v1 * inv;
		if (d2) (*d2)[c] = v2 * inv2;
	}
}

Eigen::Isometry3d BodyTrajectory::pose(double t) const
{
	Sample v;
	channels(t, v);
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	T.linear() = rotationYPR(v[3], v[4], v[5]);
	T.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
	return T;
}

BodyState BodyTrajectory::state(double t) const
{
	Sample v, d1, d2;
	channels(t, v, &d1, &d2);
	BodyState s;
	s.p = Eigen::Vector3d(v[0], v[1], v[2]);
	s.v = Eigen::Vector3d(d1[0], d1[1], d1[2]);
	s.a = Eigen::Vector3d(d2[0], d2[1], d2[2]);
	s.R = rotationYPR(v[3], v[4], v[5]);
	// Body rates of Z-Y-X Euler angles (yaw psi, pitch theta, roll phi):
	// w = Rx^T Ry^T (0,0,psi') + Rx^T (0,theta',0) + (phi',0,0).
	const double th = v[4], ph = v[5];
	const double dps = d1[3], dth = d1[4], dph = d1[5];
	const double ddps = d2[3], ddth = d2[4], ddph = d2[5];
	const double st = std::sin(th), ct = std::cos(th);
	const double sp = std::sin(ph), cp = std::cos(ph);
	s.w_body = Eigen::Vector3d(dph - dps * st, dth * cp + dps * ct * sp,
	                           -dth * sp + dps * ct * cp);
	s.dw_body = Eigen::Vector3d(ddph - ddps * st - dps * dth * ct,
	                            ddth * cp - dth * dph * sp + ddps * ct * sp -
	                                dps * dth * st * sp + dps * dph * ct * cp,
	                            -ddth * sp - dth * dph * cp + ddps * ct * cp -
	                                dps * dth * st * cp - dps * dph * ct * sp);
	return s;
}

}  // namespace forest_slam::sim
