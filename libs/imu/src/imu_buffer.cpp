#include <forest_slam/core/log.h>
#include <forest_slam/imu/imu_buffer.h>

#include <algorithm>
#include <cmath>

namespace forest_slam::imu
{
bool ImuBuffer::add(double t_s, const Eigen::Vector3d& gyro,
                    const Eigen::Vector3d& acc)
{
	if (!std::isfinite(t_s) || !gyro.allFinite() || !acc.allFinite())
		return false;
	if (!samples_.empty() && !(t_s > samples_.back().s.t_s)) return false;
	Entry e;
	e.s.t_s = t_s;
	e.s.gyro = gyro;
	e.s.acc = acc;
	// A gap (IMU stall) is not integrated through the filter: it restarts
	// the integration step from this sample. Roll and pitch changed unseen
	// during the gap; the accelerometer pulls them back, and for a while
	// (2/kp, at most 2 s) the attitude is not handed out (attitudeAt: no
	// gravity prior on a wrong "up"); the rotations between samples are.
	const double gap = samples_.empty() ? 0.0 : t_s - samples_.back().s.t_s;
	if (gap > kMaxStep_s)
		settle_until_s_ = t_s + std::min(2.0, 2.0 / std::max(0.05, kp_));
	const bool at_rest = filter_.atRestSinceStart();
	filter_.update(e.s.gyro, e.s.acc, std::min(kMaxStep_s, gap));
	if (at_rest && !filter_.atRestSinceStart() && filter_.restSamples() > 0)
	{
		const Eigen::Vector3d b = filter_.gyroBias() * 180 / M_PI;
		FS_LOG_INFO("IMU: gyro bias from the start at rest ("
		            << filter_.restSamples() << " samples, until t=" << t_s
		            << " s): " << b.x() << " " << b.y() << " " << b.z()
		            << " deg/s");
	}
	e.settling = t_s < settle_until_s_;
	e.attitude = filter_.attitude();
	e.bias = filter_.gyroBias();
	e.levelled = filter_.initialised();
	samples_.push_back(e);
	return true;
}

bool ImuBuffer::covers(double t0, double t1, double max_gap_s) const
{
	if (samples_.empty() || samples_.front().s.t_s > t0 ||
	    samples_.back().s.t_s < t1)
		return false;
	auto it = atOrBefore(t0);
	for (; it != samples_.end() && it->s.t_s < t1; ++it)
	{
		const auto nx = std::next(it);
		if (nx != samples_.end() && nx->s.t_s - it->s.t_s > max_gap_s)
			return false;
	}
	return true;
}

Eigen::Quaterniond ImuBuffer::rotationBetween(double t0, double t1) const
{
	Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
	if (samples_.size() < 2 || !(t1 > t0)) return q;
	auto it = atOrBefore(t0);
	// The bias is the filter's latest estimate: it changes slowly.
	const Eigen::Vector3d bias = samples_.back().bias;
	for (; std::next(it) != samples_.end() && it->s.t_s < t1; ++it)
	{
		const auto& a = it->s;
		const auto& b = std::next(it)->s;
		const double lo = std::max(t0, a.t_s), hi = std::min(t1, b.t_s);
		if (!(hi > lo)) continue;
		const Eigen::Vector3d w = 0.5 * (a.gyro + b.gyro) - bias;
		const Eigen::Vector3d dth = w * (hi - lo);
		const double ang = dth.norm();
		if (ang > 1e-12)
			q = q * Eigen::Quaterniond(Eigen::AngleAxisd(ang, dth / ang));
	}
	return q.normalized();
}

AccelIntegral ImuBuffer::integrateAcceleration(
    double t0, double t1, const Eigen::Vector3d& gravity_t0) const
{
	AccelIntegral out;
	if (samples_.size() < 2 || !(t1 > t0)) return out;
	auto it = atOrBefore(t0);
	const Eigen::Vector3d bias = samples_.back().bias;
	Eigen::Quaterniond q = Eigen::Quaterniond::Identity();  // R_t0_u
	// Specific force of a sample blended to time u inside [a, b].
	const auto force = [](const ImuSample& a, const ImuSample& b, double u)
	{
		const double w = (u - a.t_s) / (b.t_s - a.t_s);
		return ((1 - w) * a.acc + w * b.acc).eval();
	};
	Eigen::Vector3d v = Eigen::Vector3d::Zero(), acc_lo;
	bool first = true;
	for (; std::next(it) != samples_.end() && it->s.t_s < t1; ++it)
	{
		const auto& a = it->s;
		const auto& b = std::next(it)->s;
		const double lo = std::max(t0, a.t_s), hi = std::min(t1, b.t_s);
		if (!(hi > lo)) continue;
		const double h = hi - lo;
		if (first) acc_lo = q * force(a, b, lo) + gravity_t0, first = false;
		const Eigen::Vector3d dth = (0.5 * (a.gyro + b.gyro) - bias) * h;
		const double ang = dth.norm();
		if (ang > 1e-12)
			q = q * Eigen::Quaterniond(Eigen::AngleAxisd(ang, dth / ang));
		const Eigen::Vector3d acc_hi = q * force(a, b, hi) + gravity_t0;
		// Trapezoid on a; exact double integral of the linear a in the step.
		out.dp += v * h + h * h * (acc_lo / 3 + acc_hi / 6);
		const Eigen::Vector3d dv = 0.5 * h * (acc_lo + acc_hi);
		out.moment += h * (0.5 * ((lo - t0) * acc_lo + (hi - t0) * acc_hi));
		v += dv;
		acc_lo = acc_hi;
	}
	out.dv = v;
	out.moment /= (t1 - t0);
	return out;
}

std::optional<Eigen::Vector3d> ImuBuffer::upAt(
    double t_s, const Eigen::Matrix3d& R_body_sensor) const
{
	Eigen::Quaterniond att;
	if (!attitudeAt(t_s, att)) return std::nullopt;
	return R_body_sensor.transpose() *
	       (att.conjugate() * Eigen::Vector3d::UnitZ());
}

bool ImuBuffer::attitudeAt(double t_s, Eigen::Quaterniond& q) const
{
	if (samples_.empty() || !filter_.initialised()) return false;
	auto it = atOrBefore(t_s);
	if (it->s.t_s > t_s) return false;  // every sample is after t_s
	if (t_s - it->s.t_s > kMaxStep_s || it->settling) return false;
	if (!it->levelled)
	{
		// Before the filter levelled itself: its first levelled attitude,
		// rotated back to t with the gyro.
		auto lv = std::find_if(it, samples_.end(),
		                       [](const Entry& e) { return e.levelled; });
		q = (lv->attitude * rotationBetween(t_s, lv->s.t_s).conjugate())
		        .normalized();
		return true;
	}
	// Carry the attitude from the sample to t with its rate.
	const Eigen::Vector3d dth = (it->s.gyro - it->bias) * (t_s - it->s.t_s);
	const double ang = dth.norm();
	q = it->attitude;
	if (ang > 1e-12)
		q = q * Eigen::Quaterniond(Eigen::AngleAxisd(ang, dth / ang));
	q.normalize();
	return true;
}

void ImuBuffer::pruneBefore(double t_s)
{
	while (samples_.size() > 1 && samples_[1].s.t_s <= t_s)
		samples_.pop_front();
}

}  // namespace forest_slam::imu
