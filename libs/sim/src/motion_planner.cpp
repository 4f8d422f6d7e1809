#include <forest_slam/sim/motion_planner.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace forest_slam::sim
{
namespace
{
constexpr double kDeg = M_PI / 180.0;

double wrapPi(double a)
{
	a = std::fmod(a + M_PI, 2 * M_PI);
	if (a < 0) a += 2 * M_PI;
	return a - M_PI;
}

double quintic(double x)
{
	x = std::clamp(x, 0.0, 1.0);
	return x * x * x * (10 + x * (-15 + 6 * x));
}
double quinticDerivative(double x)
{
	if (x <= 0 || x >= 1) return 0;
	return 30 * x * x * (1 - x) * (1 - x);
}

/** Appends points from a to b (excluded) every <= spacing. */
void appendLine(std::vector<Eigen::Vector2d>& pts, const Eigen::Vector2d& a,
                const Eigen::Vector2d& b, double spacing)
{
	const int n =
	    std::max(1, static_cast<int>(std::ceil((b - a).norm() / spacing)));
	for (int i = 0; i < n; i++) pts.push_back(a + (b - a) * (double(i) / n));
}

/** Centred moving average over +-half samples, clamped at the ends: the
 * ends are at rest, so they keep their exact values. */
void smoothChannel(std::vector<BodyTrajectory::Sample>& s, int ch, int half)
{
	if (half <= 0) return;
	const int n = static_cast<int>(s.size());
	std::vector<double> src(n), pre(n + 1, 0.0);
	for (int i = 0; i < n; i++) src[i] = s[i][ch];
	for (int i = 0; i < n; i++) pre[i + 1] = pre[i] + src[i];
	for (int i = 0; i < n; i++)
	{
		const int a = i - half, b = i + half;
		if (a >= 0 && b < n)
			s[i][ch] = (pre[b + 1] - pre[a]) / (2 * half + 1);
		else
		{
			double sum = 0;
			for (int j = a; j <= b; j++) sum += src[std::clamp(j, 0, n - 1)];
			s[i][ch] = sum / (2 * half + 1);
		}
	}
	// Bit-exact rest at both ends: a run of identical inputs averages to a
	// value that can differ in the last bit; restore the raw values there.
	for (int i = 0; i < n; i++)
	{
		bool flat = true;
		for (int j = i - half; j <= i + half && flat; j++)
			flat = src[std::clamp(j, 0, n - 1)] == src[i];
		if (flat) s[i][ch] = src[i];
	}
}

/** Band-limited wobble: a sum of four sinusoids with random frequencies
 * around `f_hz`, peak amplitude at most 1. */
struct Wobble
{
	double f[4], ph[4];
	Wobble(Rng& rng, double f_hz, double spread = 0.4)
	{
		for (int i = 0; i < 4; i++)
		{
			f[i] = f_hz * rng.uniform(1 - spread, 1 + spread);
			ph[i] = rng.uniform(0, 2 * M_PI);
		}
	}
	double operator()(double t) const
	{
		double v = 0;
		for (int i = 0; i < 4; i++) v += std::sin(2 * M_PI * f[i] * t + ph[i]);
		return 0.25 * v;
	}
};
}  // namespace

PathPlan PathPlan::make(const MotionOptions& o, Rng& rng)
{
	PathPlan p;
	p.type_ = o.motionType();
	const double rx = o.loop_radius_x_m, ry = o.loop_radius_y_m;
	if (p.type_ == MotionType::Handheld)
	{
		// Big loop: an irregular ellipse through the start (its south point),
		// walked counter-clockwise, starting eastwards.
		double amp[3], ph[3];
		for (int k = 0; k < 3; k++)
		{
			amp[k] = rng.uniform(0.5, 1.0) / 3.0;
			ph[k] = rng.uniform(0, 2 * M_PI);
		}
		auto f = [&](double th)
		{
			double v = 0;
			for (int k = 0; k < 3; k++)
				v += amp[k] * std::sin((k + 2) * th + ph[k]);
			return v;
		};
		const double th0 = -M_PI / 2;
		auto loopPoint = [&](double th)
		{
			const double rho = 1 + o.loop_wobble * (f(th) - f(th0));
			return Eigen::Vector2d(rx * rho * std::cos(th),
			                       ry + ry * rho * std::sin(th));
		};
		const double perimeter =
		    2 * M_PI * std::sqrt(0.5 * (rx * rx + ry * ry));
		const int n = std::max(8, static_cast<int>(std::ceil(perimeter / 4.0)));
		std::vector<Eigen::Vector2d> c;
		c.emplace_back(0, 0);
		for (int j = 1; j < n; j++)
			c.push_back(loopPoint(th0 + 2 * M_PI * j / n));
		const double ri = o.inner_loop_radius_m;
		if (ri > 0)
		{
			// Inner loop centred in the big one, reached by walking north on
			// x=+3 and left by walking south on x=-3, walked clockwise.
			const double qy = ry - ri, off = 3.0;
			appendLine(c, {off, 0}, {off, qy}, 4.0);
			const int m =
			    std::max(8, static_cast<int>(std::ceil(2 * M_PI * ri / 4.0)));
			c.emplace_back(off, qy);
			for (int j = 0; j <= m; j++)
			{
				const double a = -M_PI / 2 - 2 * M_PI * j / m;
				c.emplace_back(ri * std::cos(a), qy + ri + ri * std::sin(a));
			}
			appendLine(c, {-off, qy}, {-off, 0}, 4.0);
			c.emplace_back(-off, 0);
		}
		p.ctrl_ = c;
		// Shift so that the curve starts exactly at the origin.
		const Eigen::Vector2d start = p.curve(0);
		for (auto& q : p.ctrl_) q -= start;
		// Arc length table.
		const int N = static_cast<int>(p.ctrl_.size());
		const int per_seg = 64;
		p.table_u_.push_back(0);
		p.table_s_.push_back(0);
		Eigen::Vector2d prev = p.curve(0);
		for (int i = 1; i <= N * per_seg; i++)
		{
			const double u = static_cast<double>(i) / per_seg;
			const Eigen::Vector2d q = p.curve(u);
			p.table_u_.push_back(u);
			p.table_s_.push_back(p.table_s_.back() + (q - prev).norm());
			prev = q;
		}
		p.length_ = p.table_s_.back();
	}
	else
	{
		// Robot: rectangle corners around (0, ry), jittered on every lap.
		const double j = o.corner_jitter_m;
		auto jit = [&]()
		{ return Eigen::Vector2d(rng.uniform(-j, j), rng.uniform(-j, j)); };
		p.waypoints_.emplace_back(0, 0);
		for (int lap = 0; o.route == "out_and_back" && lap < o.loops; lap++)
		{
			// Out along a straight line and back on it: every place is seen
			// again from the other direction, and stretches look alike.
			p.waypoints_.emplace_back(2 * rx, 0);
			p.waypoints_.emplace_back(0, 0);
		}
		for (int lap = 0; o.route == "loop" && lap < o.loops; lap++)
		{
			p.waypoints_.push_back(Eigen::Vector2d(rx, 0) + jit());
			p.waypoints_.push_back(Eigen::Vector2d(rx, 2 * ry) + jit());
			p.waypoints_.push_back(Eigen::Vector2d(-rx, 2 * ry) + jit());
			p.waypoints_.push_back(Eigen::Vector2d(-rx, 0) + jit());
			p.waypoints_.emplace_back(0, 0);
		}
		p.cum_len_.push_back(0);
		for (size_t i = 1; i < p.waypoints_.size(); i++)
			p.cum_len_.push_back(
			    p.cum_len_.back() +
			    (p.waypoints_[i] - p.waypoints_[i - 1]).norm());
		p.length_ = p.cum_len_.back();
	}
	return p;
}

Eigen::Vector2d PathPlan::curve(double u, Eigen::Vector2d* du) const
{
	const int N = static_cast<int>(ctrl_.size());
	u = std::fmod(u, static_cast<double>(N));
	if (u < 0) u += N;
	const int i = std::min(static_cast<int>(std::floor(u)), N - 1);
	const double w = u - i, w2 = w * w, w3 = w2 * w, m = 1 - w;
	const double b[4] = {m * m * m / 6, (3 * w3 - 6 * w2 + 4) / 6,
	                     (-3 * w3 + 3 * w2 + 3 * w + 1) / 6, w3 / 6};
	const double db[4] = {-0.5 * m * m, 1.5 * w2 - 2 * w, -1.5 * w2 + w + 0.5,
	                      0.5 * w2};
	Eigen::Vector2d v(0, 0), d(0, 0);
	for (int j = 0; j < 4; j++)
	{
		const auto& c = ctrl_[((i + j - 1) % N + N) % N];
		v += b[j] * c;
		d += db[j] * c;
	}
	if (du) *du = d;
	return v;
}

double PathPlan::paramAt(double s) const
{
	if (s <= 0 || s >= length_) return 0.0;  // closed: the end is the start
	const auto it = std::upper_bound(table_s_.begin(), table_s_.end(), s);
	const size_t i = static_cast<size_t>(it - table_s_.begin());
	const double s0 = table_s_[i - 1], s1 = table_s_[i];
	const double a = s1 > s0 ? (s - s0) / (s1 - s0) : 0;
	return table_u_[i - 1] + a * (table_u_[i] - table_u_[i - 1]);
}

Eigen::Vector2d PathPlan::point(double s) const
{
	if (type_ == MotionType::Handheld) return curve(paramAt(s));
	s = std::clamp(s, 0.0, length_);
	const auto it = std::upper_bound(cum_len_.begin(), cum_len_.end(), s);
	const size_t i = std::min(static_cast<size_t>(it - cum_len_.begin()),
	                          waypoints_.size() - 1);
	const double l = cum_len_[i] - cum_len_[i - 1];
	const double a = l > 0 ? (s - cum_len_[i - 1]) / l : 0;
	return waypoints_[i - 1] + a * (waypoints_[i] - waypoints_[i - 1]);
}

Eigen::Vector2d PathPlan::tangent(double s) const
{
	if (type_ == MotionType::Handheld)
	{
		Eigen::Vector2d d;
		curve(paramAt(s), &d);
		return d.normalized();
	}
	s = std::clamp(s, 0.0, length_);
	const auto it = std::upper_bound(cum_len_.begin(), cum_len_.end(), s);
	const size_t i = std::min(static_cast<size_t>(it - cum_len_.begin()),
	                          waypoints_.size() - 1);
	return (waypoints_[i] - waypoints_[i - 1]).normalized();
}

std::vector<Eigen::Vector2d> PathPlan::sample(double spacing_m) const
{
	std::vector<Eigen::Vector2d> out;
	const int n = std::max(1, static_cast<int>(std::ceil(length_ / spacing_m)));
	for (int i = 0; i <= n; i++) out.push_back(point(length_ * i / n));
	return out;
}

namespace
{
/** Handheld: walk along the closed curve with a wandering speed, a gait
 * (bobbing at the step frequency, roll at the stride frequency, pitch and
 * yaw sway) that fades in and out with the speed. */
std::vector<BodyTrajectory::Sample> handheldDesign(const PathPlan& path,
                                                   const MotionOptions& o,
                                                   const Terrain& terrain,
                                                   double dt, Rng& rng)
{
	const double L = path.length();
	const double v_nom = 0.5 * (o.speed_min_mps + o.speed_max_mps);
	const double v_amp = 0.5 * (o.speed_max_mps - o.speed_min_mps);
	const double ph1 = rng.uniform(0, 2 * M_PI), ph2 = rng.uniform(0, 2 * M_PI);
	const Wobble wr(rng, 0.15), wp(rng, 0.2), wy(rng, 0.1);
	const double sway = o.sway_deg * kDeg;

	std::vector<BodyTrajectory::Sample> out;
	std::vector<double> ground;
	double s = 0, v = 0, gait_phase = 0, m = -dt;
	const Eigen::Vector2d t0v = path.tangent(0);
	const double yaw0 = std::atan2(t0v.y(), t0v.x());
	double yaw_prev = yaw0;
	bool arrived = false;
	double t_arrived = 0;
	while (true)
	{
		if (m >= o.start_pause_s && !arrived)
		{
			const double v_target =
			    v_nom + v_amp * (0.6 * std::sin(2 * M_PI * m / 40 + ph1) +
			                     0.4 * std::sin(2 * M_PI * m / 13 + ph2));
			const double v_brake =
			    std::sqrt(2 * o.accel_mps2 * std::max(0.0, L - s));
			v = std::min({v_target, v + o.accel_mps2 * dt, v_brake});
			s += v * dt;
			if (s >= L - 1e-6 || (v < 1e-4 && L - s < 1e-3))
			{
				s = L;
				v = 0;
				arrived = true;
				t_arrived = m;
			}
			gait_phase +=
			    2 * M_PI * o.step_frequency_hz * std::min(1.0, v / v_nom) * dt;
		}
		if (arrived && m > t_arrived + o.end_pause_s) break;
		const Eigen::Vector2d p = path.point(s);
		const Eigen::Vector2d tg = path.tangent(s);
		double yaw = yaw_prev + wrapPi(std::atan2(tg.y(), tg.x()) - yaw_prev);
		yaw_prev = yaw;
		if (arrived)
			yaw = yaw0 + 2 * M_PI * std::round((yaw - yaw0) / (2 * M_PI));
		const double env = std::clamp(v / o.speed_min_mps, 0.0, 1.0);
		const double g = gait_phase;
		BodyTrajectory::Sample smp;
		smp[0] = p.x();
		smp[1] = p.y();
		smp[2] = o.body_height_m + o.bob_amplitude_m * env * std::sin(2 * g);
		smp[3] =
		    yaw + 0.5 * sway * env * (0.6 * std::sin(g + 1.0) + 0.4 * wy(m));
		smp[4] = 0.6 * sway * env * (0.6 * std::sin(2 * g + 0.5) + 0.4 * wp(m));
		smp[5] = sway * env * (0.7 * std::sin(g) + 0.3 * wr(m));
		out.push_back(smp);
		ground.push_back(terrain.smoothHeight(p.x(), p.y()));
		m += dt;
	}
	// The walker's legs absorb the small bumps: follow the ground smoothed
	// over half a second.
	const int half = static_cast<int>(std::round(0.25 / dt));
	std::vector<BodyTrajectory::Sample> gs(ground.size());
	for (size_t i = 0; i < ground.size(); i++) gs[i][0] = ground[i];
	smoothChannel(gs, 0, half);
	for (size_t i = 0; i < out.size(); i++) out[i][2] += gs[i][0];
	return out;
}

/** Robot: pauses, straight drives with smooth speed ramps and in-place
 * turns; attitude from the four wheel contacts, vibration while moving. */
struct Phase
{
	enum Kind
	{
		Pause,
		Drive,
		Turn
	} kind;
	double t_start = 0, duration = 0;
	Eigen::Vector2d p0, p1;
	double yaw0 = 0, yaw1 = 0;
	double v = 0, t_acc = 0;
};

struct RobotPose
{
	Eigen::Vector2d p;
	double yaw = 0, activity = 0;  ///< 0 at rest .. 1 full speed / turn rate
};

RobotPose evalPhase(const Phase& ph, double t, const MotionOptions& o)
{
	RobotPose r;
	const double tau = std::clamp(t - ph.t_start, 0.0, ph.duration);
	r.p = ph.p0;
	r.yaw = ph.yaw0;
	if (ph.kind == Phase::Drive)
	{
		const double L = (ph.p1 - ph.p0).norm();
		const double ta = ph.t_acc, T = ph.duration;
		// Speed ramps with a cubic smoothstep S(x)=3x^2-2x^3, whose
		// integral is x^3 - x^4/2.
		double s, v;
		if (tau < ta)
		{
			const double x = tau / ta;
			s = ph.v * ta * (x * x * x - 0.5 * x * x * x * x);
			v = ph.v * x * x * (3 - 2 * x);
		}
		else if (tau > T - ta)
		{
			const double x = (T - tau) / ta;
			s = L - ph.v * ta * (x * x * x - 0.5 * x * x * x * x);
			v = ph.v * x * x * (3 - 2 * x);
		}
		else
		{
			s = 0.5 * ph.v * ta + ph.v * (tau - ta);
			v = ph.v;
		}
		r.p = ph.p0 + (ph.p1 - ph.p0) * (L > 0 ? s / L : 0);
		r.activity = v / o.speed_max_mps;
	}
	else if (ph.kind == Phase::Turn)
	{
		const double x = tau / ph.duration;
		r.yaw = ph.yaw0 + (ph.yaw1 - ph.yaw0) * quintic(x);
		const double rate =
		    std::abs(ph.yaw1 - ph.yaw0) * quinticDerivative(x) / ph.duration;
		r.activity = rate / (o.turn_rate_deg_s * kDeg);
	}
	r.activity = std::clamp(r.activity, 0.0, 1.0);
	return r;
}

std::vector<BodyTrajectory::Sample> robotDesign(const PathPlan& path,
                                                const MotionOptions& o,
                                                const Terrain& terrain,
                                                double dt, Rng& rng)
{
	const auto& w = path.waypoints();
	std::vector<Phase> phases;
	double t = 0;
	auto push = [&](Phase ph)
	{
		ph.t_start = t;
		t += ph.duration;
		phases.push_back(ph);
	};
	auto drive =
	    [&](const Eigen::Vector2d& a, const Eigen::Vector2d& b, double yaw)
	{
		Phase ph;
		ph.kind = Phase::Drive;
		ph.p0 = a;
		ph.p1 = b;
		ph.yaw0 = ph.yaw1 = yaw;
		const double L = (b - a).norm();
		ph.v = rng.uniform(o.speed_min_mps, o.speed_max_mps);
		ph.t_acc = 1.5 * ph.v / o.accel_mps2;
		if (L < ph.v * ph.t_acc)
		{
			ph.v = std::sqrt(L * o.accel_mps2 / 1.5);
			ph.t_acc = 1.5 * ph.v / o.accel_mps2;
		}
		ph.duration =
		    ph.v > 0 ? 2 * ph.t_acc + (L - ph.v * ph.t_acc) / ph.v : 0;
		if (ph.duration > 0) push(ph);
	};
	auto pause = [&](const Eigen::Vector2d& p, double yaw, double d)
	{
		Phase ph;
		ph.kind = Phase::Pause;
		ph.p0 = ph.p1 = p;
		ph.yaw0 = ph.yaw1 = yaw;
		ph.duration = d;
		push(ph);
	};
	auto turn = [&](const Eigen::Vector2d& p, double from, double to)
	{
		if (std::abs(to - from) < 1e-9) return;
		pause(p, from, 0.5);
		Phase ph;
		ph.kind = Phase::Turn;
		ph.p0 = ph.p1 = p;
		ph.yaw0 = from;
		ph.yaw1 = to;
		// Quintic profile peaks at 1.875x its mean rate.
		ph.duration = std::max(
		    0.5, 1.875 * std::abs(to - from) / (o.turn_rate_deg_s * kDeg));
		push(ph);
		pause(p, to, 0.5);
	};

	const double yaw_start =
	    std::atan2(w[1].y() - w[0].y(), w[1].x() - w[0].x());
	double yaw = yaw_start;
	pause(w[0], yaw, o.start_pause_s);
	for (size_t i = 0; i + 1 < w.size(); i++)
	{
		const Eigen::Vector2d d = w[i + 1] - w[i];
		const double h = yaw + wrapPi(std::atan2(d.y(), d.x()) - yaw);
		turn(w[i], yaw, h);
		yaw = h;
		if (rng.uniform() < o.stop_probability)
		{
			const Eigen::Vector2d mid = w[i] + d * rng.uniform(0.3, 0.7);
			drive(w[i], mid, yaw);
			pause(mid, yaw, o.stop_duration_s * rng.uniform(0.5, 1.5));
			drive(mid, w[i + 1], yaw);
		}
		else
			drive(w[i], w[i + 1], yaw);
	}
	// Back at the start: turn to the start heading (plus whole turns).
	const double yaw_end =
	    yaw_start + 2 * M_PI * std::round((yaw - yaw_start) / (2 * M_PI));
	turn(w.back(), yaw, yaw_end);
	pause(w.back(), yaw_end, o.end_pause_s);
	const double t_total = t;

	const Wobble vz(rng, o.vibration_frequency_hz),
	    vp(rng, o.vibration_frequency_hz), vr(rng, o.vibration_frequency_hz);
	std::vector<BodyTrajectory::Sample> out;
	std::vector<double> activity;
	size_t k = 0;
	const double half_wb = 0.4, half_track = 0.3;  // wheel base / track halves
	const long n_samples =
	    static_cast<long>(std::floor(t_total / dt + 1e-9)) + 2;
	for (long i = 0; i < n_samples; i++)
	{
		const double m = (i - 1) * dt;
		while (k + 1 < phases.size() && m >= phases[k + 1].t_start) k++;
		const RobotPose r = evalPhase(phases[k], m, o);
		const Eigen::Vector2d f(std::cos(r.yaw), std::sin(r.yaw));
		const Eigen::Vector2d l(-f.y(), f.x());
		auto h = [&](double a, double b)
		{
			const Eigen::Vector2d q = r.p + a * f + b * l;
			return terrain.smoothHeight(q.x(), q.y());
		};
		const double fl = h(half_wb, half_track), fr = h(half_wb, -half_track);
		const double rl = h(-half_wb, half_track),
		             rr = h(-half_wb, -half_track);
		BodyTrajectory::Sample s;
		s[0] = r.p.x();
		s[1] = r.p.y();
		s[2] = 0.25 * (fl + fr + rl + rr);
		s[3] = r.yaw;
		s[4] = -std::atan((0.5 * (fl + fr) - 0.5 * (rl + rr)) / (2 * half_wb));
		s[5] =
		    std::atan((0.5 * (fl + rl) - 0.5 * (fr + rr)) / (2 * half_track));
		out.push_back(s);
		activity.push_back(r.activity);
	}
	// Suspension and tyres filter the bilinear terrain's kinks (0.2 s).
	const int half = static_cast<int>(std::round(0.1 / dt));
	for (int ch : {2, 4, 5}) smoothChannel(out, ch, half);
	const double vib = o.vibration_deg * kDeg;
	for (size_t i = 0; i < out.size(); i++)
	{
		const double m = (static_cast<double>(i) - 1) * dt, a = activity[i];
		out[i][2] += o.body_height_m + o.vibration_z_m * a * vz(m);
		out[i][4] += vib * a * vp(m);
		out[i][5] += vib * a * vr(m);
	}
	return out;
}
}  // namespace

BodyTrajectory planBodyTrajectory(const PathPlan& path, const MotionOptions& o,
                                  const Terrain& terrain, double t0, Rng& rng)
{
	const double dt = o.knot_spacing_s;
	std::vector<BodyTrajectory::Sample> ctrl =
	    path.type() == MotionType::Handheld
	        ? handheldDesign(path, o, terrain, dt, rng)
	        : robotDesign(path, o, terrain, dt, rng);
	// Two more rest samples so the last knot interval ends at rest.
	ctrl.push_back(ctrl.back());
	ctrl.push_back(ctrl.back());
	return BodyTrajectory(t0, dt, std::move(ctrl));
}

}  // namespace forest_slam::sim
