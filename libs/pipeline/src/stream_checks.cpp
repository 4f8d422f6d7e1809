#include <forest_slam/pipeline/stream_checks.h>

#include <algorithm>
#include <cmath>

namespace forest_slam::pipeline
{
double GapDetector::observe(double t)
{
	if (!have_)
	{
		have_ = true;
		last_s_ = t;
		return 0;
	}
	const double dt = t - last_s_;
	last_s_ = t;
	if (!(dt > 0)) return 0;
	// The typical interval: the smallest seen recently. It is allowed to
	// grow slowly (a rate change) but a single gap does not move it.
	const bool gap =
	    intervals_ >= 3 && dt > factor_ * typical_s_ && dt > min_gap_s_;
	if (intervals_ == 0 || dt < typical_s_)
		typical_s_ = dt;
	else if (!gap)
		typical_s_ += 0.01 * (dt - typical_s_);
	intervals_++;
	return gap ? dt : 0.0;
}

double GnssJumpCheck::horizontalDistance(double lat0, double lon0, double lat1,
                                         double lon1)
{
	// Equirectangular: exact enough for the metres to kilometres compared.
	constexpr double R = 6371000.0, d2r = M_PI / 180.0;
	const double dy = (lat1 - lat0) * d2r * R;
	const double dx =
	    (lon1 - lon0) * d2r * R * std::cos(0.5 * (lat0 + lat1) * d2r);
	return std::hypot(dx, dy);
}

GnssJumpCheck::Verdict GnssJumpCheck::observe(double t, double lat, double lon,
                                              double& dist)
{
	dist = 0;
	if (!have_)
	{
		have_ = true;
		t_ = t;
		lat_ = lat;
		lon_ = lon;
		return Verdict::Accepted;
	}
	dist = horizontalDistance(lat_, lon_, lat, lon);
	const double allowed = max_speed_ * std::max(0.0, t - t_) + tolerance_;
	if (dist <= allowed)
	{
		t_ = t;
		lat_ = lat;
		lon_ = lon;
		jumping_ = false;
		return Verdict::Accepted;
	}
	// Rejected: does it agree with the previous rejected fixes?
	if (jumping_ && horizontalDistance(jump_lat_, jump_lon_, lat, lon) <=
	                    max_speed_ * std::max(0.0, t - jump_t0_) + tolerance_)
	{
		if (t - jump_t0_ >= reanchor_s_)
		{
			t_ = t;
			lat_ = lat;
			lon_ = lon;
			jumping_ = false;
			return Verdict::Reanchored;
		}
		return Verdict::Jump;
	}
	jumping_ = true;
	jump_t0_ = t;
	jump_lat_ = lat;
	jump_lon_ = lon;
	return Verdict::Jump;
}

}  // namespace forest_slam::pipeline
