#include <forest_slam/eval/trajectory_metrics.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace forest_slam::eval
{
namespace
{
constexpr double kRadToDeg = 180.0 / M_PI;

double yawOf(const Eigen::Matrix3d& R)
{
	return std::atan2(R(1, 0), R(0, 0));
}

std::string fmtTime(double t)
{
	char buf[64];
	std::snprintf(buf, sizeof(buf), "%.3f", t);
	return buf;
}
}  // namespace

double rotationAngleDeg(const Eigen::Matrix3d& R)
{
	// AngleAxis is accurate near 0 where acos((trace-1)/2) loses digits.
	return std::abs(
	           Eigen::AngleAxisd(Eigen::Quaterniond(R).normalized()).angle()) *
	       kRadToDeg;
}

Eigen::Vector3d rollPitchYawDeg(const Eigen::Matrix3d& R)
{
	const double pitch = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
	const double roll = std::atan2(R(2, 1), R(2, 2));
	const double yaw = std::atan2(R(1, 0), R(0, 0));
	return Eigen::Vector3d(roll, pitch, yaw) * kRadToDeg;
}

Association associateByInterpolation(const core::Trajectory& gt,
                                     const core::Trajectory& est,
                                     const AssociationOptions& opts)
{
	if (gt.empty())
		throw std::runtime_error("ground-truth trajectory is empty");
	if (est.empty()) throw std::runtime_error("estimated trajectory is empty");
	Association out;
	for (const auto& e : est)
	{
		Eigen::Isometry3d g;
		if (!core::interpolatePose(gt, e.t_s, g))
		{
			out.est_outside_gt++;
			continue;
		}
		// Bracketing GT samples: reject interpolation across a hole.
		const auto it = std::lower_bound(
		    gt.begin(), gt.end(), e.t_s,
		    [](const core::StampedPose& p, double v) { return p.t_s < v; });
		if (it != gt.begin() && it != gt.end() && it->t_s != e.t_s &&
		    it->t_s - (it - 1)->t_s > opts.max_gt_gap_s)
		{
			out.est_in_gt_gap++;
			continue;
		}
		PosePair p;
		p.t_s = e.t_s;
		p.gt = g;
		p.est = e.pose;
		out.pairs.push_back(p);
	}
	if (out.pairs.empty())
		throw std::runtime_error(
		    "no estimated pose lies within the ground-truth time span (GT " +
		    fmtTime(gt.front().t_s) + " .. " + fmtTime(gt.back().t_s) +
		    " s, estimate " + fmtTime(est.front().t_s) + " .. " +
		    fmtTime(est.back().t_s) + " s" +
		    (out.est_in_gt_gap ? ", or all fall in GT gaps" : "") +
		    "): the two files do not overlap in time");
	return out;
}

std::vector<double> gtDistanceTravelled(const PosePairs& pairs)
{
	std::vector<double> d(pairs.size(), 0.0);
	for (size_t i = 1; i < pairs.size(); i++)
		d[i] =
		    d[i - 1] +
		    (pairs[i].gt.translation() - pairs[i - 1].gt.translation()).norm();
	return d;
}

Eigen::Isometry3d umeyamaSe3(const std::vector<Eigen::Vector3d>& src,
                             const std::vector<Eigen::Vector3d>& dst)
{
	if (src.size() != dst.size() || src.empty())
		throw std::invalid_argument(
		    "umeyamaSe3: need equal, non-empty point sets");
	Eigen::Matrix3Xd s(3, src.size()), d(3, dst.size());
	for (size_t i = 0; i < src.size(); i++)
	{
		s.col(static_cast<Eigen::Index>(i)) = src[i];
		d.col(static_cast<Eigen::Index>(i)) = dst[i];
	}
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	T.matrix() = Eigen::umeyama(s, d, false);
	return T;
}

AteResult absoluteTrajectoryError(const PosePairs& pairs, bool align_se3)
{
	AteResult r;
	if (pairs.empty()) return r;
	if (align_se3)
	{
		std::vector<Eigen::Vector3d> src, dst;
		for (const auto& p : pairs)
		{
			src.push_back(p.est.translation());
			dst.push_back(p.gt.translation());
		}
		r.alignment = umeyamaSe3(src, dst);
	}
	std::vector<double> te, re;
	for (const auto& p : pairs)
	{
		const Eigen::Isometry3d e = r.alignment * p.est;
		te.push_back((p.gt.translation() - e.translation()).norm());
		re.push_back(rotationAngleDeg(p.gt.linear().transpose() * e.linear()));
	}
	r.trans_m = summarize(te);
	r.rot_deg = summarize(re);
	return r;
}

RpeResult relativePoseError(const PosePairs& pairs, const RpeOptions& opts)
{
	RpeResult r;
	const auto dist = gtDistanceTravelled(pairs);
	double sum_t = 0, sum_r = 0;
	for (double L : opts.lengths_m)
	{
		if (!(L > 0))
			throw std::invalid_argument("RPE segment lengths must be > 0");
		RpeLengthResult lr;
		lr.length_m = L;
		double lt = 0, lrot = 0;
		for (size_t i = 0; i < pairs.size(); i++)
		{
			// The micrometre slack keeps a segment whose length is L up to
			// the rounding of the cumulative sum.
			const auto it =
			    std::lower_bound(dist.begin() + static_cast<long>(i),
			                     dist.end(), dist[i] + L - 1e-6);
			if (it == dist.end()) break;  // later starts are shorter still
			const size_t j = static_cast<size_t>(it - dist.begin());
			const Eigen::Isometry3d dg = pairs[i].gt.inverse() * pairs[j].gt;
			const Eigen::Isometry3d de = pairs[i].est.inverse() * pairs[j].est;
			const Eigen::Isometry3d E = de.inverse() * dg;
			lt += E.translation().norm() / L;
			lrot += rotationAngleDeg(E.linear()) / L;
			lr.segments++;
		}
		if (lr.segments)
		{
			lr.trans_err_pct = 100.0 * lt / static_cast<double>(lr.segments);
			lr.rot_err_deg_per_m = lrot / static_cast<double>(lr.segments);
		}
		sum_t += lt;
		sum_r += lrot;
		r.segments += lr.segments;
		r.per_length.push_back(lr);
	}
	if (r.segments)
	{
		r.trans_err_pct = 100.0 * sum_t / static_cast<double>(r.segments);
		r.rot_err_deg_per_m = sum_r / static_cast<double>(r.segments);
	}
	return r;
}

VerticalDrift verticalDrift(const PosePairs& pairs)
{
	VerticalDrift v;
	if (pairs.empty()) return v;
	const auto dist = gtDistanceTravelled(pairs);
	v.distance_m = dist.back();
	const double ze0 = pairs.front().est.translation().z();
	const double zg0 = pairs.front().gt.translation().z();
	v.max_abs_err_m = 0;
	for (const auto& p : pairs)
	{
		const double e =
		    (p.est.translation().z() - ze0) - (p.gt.translation().z() - zg0);
		v.max_abs_err_m = std::max(v.max_abs_err_m, std::abs(e));
		v.end_abs_err_m = std::abs(e);
	}
	if (v.distance_m > 0)
	{
		v.end_pct = 100.0 * v.end_abs_err_m / v.distance_m;
		v.max_pct = 100.0 * v.max_abs_err_m / v.distance_m;
	}
	return v;
}

namespace
{
/** Fills the components from a relative rotation and a level-frame
 * displacement (see ReturnToStartError). */
ReturnToStartError closureFrom(const Eigen::Matrix3d& R_rel,
                               const Eigen::Vector3d& d_level, double t0,
                               double t1)
{
	ReturnToStartError r;
	r.t_first_s = t0;
	r.t_last_s = t1;
	const Eigen::Vector3d rpy = rollPitchYawDeg(R_rel);
	r.roll_deg = rpy.x();
	r.pitch_deg = rpy.y();
	r.yaw_deg = rpy.z();
	r.total_rot_deg = rpy.norm();
	r.angle_deg = rotationAngleDeg(R_rel);
	r.x_m = d_level.x();
	r.y_m = d_level.y();
	r.z_m = d_level.z();
	r.total_trans_m = d_level.norm();
	return r;
}

Eigen::Vector3d levelDisplacement(const Eigen::Isometry3d& first,
                                  const Eigen::Isometry3d& last)
{
	const Eigen::Matrix3d Rz =
	    Eigen::AngleAxisd(yawOf(first.linear()), Eigen::Vector3d::UnitZ())
	        .toRotationMatrix();
	return Rz.transpose() * (last.translation() - first.translation());
}
}  // namespace

ReturnToStartError returnToStartError(const core::StampedPose& first,
                                      const core::StampedPose& last)
{
	return closureFrom(first.pose.linear().transpose() * last.pose.linear(),
	                   levelDisplacement(first.pose, last.pose), first.t_s,
	                   last.t_s);
}

ReturnToStartError returnToStartError(const core::Trajectory& traj)
{
	if (traj.empty())
		throw std::runtime_error(
		    "return-to-start error of an empty trajectory");
	return returnToStartError(traj.front(), traj.back());
}

ReturnToStartError returnToStartErrorVsGt(const core::StampedPose& est_first,
                                          const core::StampedPose& est_last,
                                          const Eigen::Isometry3d& gt_first,
                                          const Eigen::Isometry3d& gt_last)
{
	const Eigen::Matrix3d Re =
	    est_first.pose.linear().transpose() * est_last.pose.linear();
	const Eigen::Matrix3d Rg = gt_first.linear().transpose() * gt_last.linear();
	return closureFrom(Rg.transpose() * Re,
	                   levelDisplacement(est_first.pose, est_last.pose) -
	                       levelDisplacement(gt_first, gt_last),
	                   est_first.t_s, est_last.t_s);
}

GnssDriftResult gnssDrift(const core::Trajectory& est,
                          const PositionTrack& gnss,
                          const GnssDriftOptions& opts)
{
	if (!(opts.interval_s > 0))
		throw std::invalid_argument("GNSS drift interval must be > 0");
	if (est.empty()) throw std::runtime_error("estimated trajectory is empty");
	if (gnss.empty()) throw std::runtime_error("GNSS track is empty");
	GnssDriftResult r;
	const double t0 = std::max(est.front().t_s, gnss.front().t_s);
	const double t1 = std::min(est.back().t_s, gnss.back().t_s);
	if (t0 > t1)
		throw std::runtime_error(
		    "GNSS track (" + fmtTime(gnss.front().t_s) + " .. " +
		    fmtTime(gnss.back().t_s) + " s) and estimate (" +
		    fmtTime(est.front().t_s) + " .. " + fmtTime(est.back().t_s) +
		    " s) do not overlap in time");
	r.t0_s = t0;
	std::vector<double> d3, d2;
	// Integer step count avoids accumulating rounding in t0 + k * interval.
	for (size_t k = 0;; k++)
	{
		const double tk = t0 + static_cast<double>(k) * opts.interval_s;
		if (tk > t1 + 1e-9) break;
		r.sample_times++;
		const auto it = std::lower_bound(gnss.begin(), gnss.end(), tk,
		                                 [](const PositionFix& f, double v)
		                                 { return f.t_s < v; });
		const PositionFix* best = nullptr;
		if (it != gnss.end()) best = &*it;
		if (it != gnss.begin() &&
		    (!best || tk - (it - 1)->t_s < best->t_s - tk))
			best = &*(it - 1);
		Eigen::Isometry3d pe;
		if (!best || std::abs(best->t_s - tk) > opts.max_fix_offset_s ||
		    !core::interpolatePose(est, best->t_s, pe))
		{
			r.skipped_no_fix++;
			continue;
		}
		GnssDriftSample s;
		s.t_s = best->t_s;
		s.est = pe.translation();
		s.gnss = best->p;
		s.dist_3d_m = (s.est - s.gnss).norm();
		s.dist_2d_m = (s.est - s.gnss).head<2>().norm();
		d3.push_back(s.dist_3d_m);
		d2.push_back(s.dist_2d_m);
		r.samples.push_back(s);
	}
	r.dist_3d_m = summarize(d3);
	r.dist_2d_m = summarize(d2);
	if (r.samples.size() >= 3)
	{
		std::vector<Eigen::Vector3d> src, dst;
		for (const auto& s : r.samples)
		{
			src.push_back(s.est);
			dst.push_back(s.gnss);
		}
		r.alignment = umeyamaSe3(src, dst);
		std::vector<double> da;
		for (auto& s : r.samples)
		{
			s.aligned_dist_3d_m = (r.alignment * s.est - s.gnss).norm();
			da.push_back(s.aligned_dist_3d_m);
		}
		r.aligned_dist_3d_m = summarize(da);
	}
	return r;
}

}  // namespace forest_slam::eval
