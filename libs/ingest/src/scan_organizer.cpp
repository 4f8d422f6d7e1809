#include <forest_slam/core/log.h>
#include <forest_slam/ingest/scan_organizer.h>
#include <forest_slam/ingest/stamps.h>

#include <mrpt/system/datetime.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace forest_slam::ingest
{
namespace
{
constexpr double kTwoPi = 2 * M_PI;

double wrapPi(double a)
{
	a = std::fmod(a + M_PI, kTwoPi);
	if (a < 0) a += kTwoPi;
	return a - M_PI;
}

double median(std::vector<double> v)
{
	if (v.empty()) return std::nan("");
	const size_t m = v.size() / 2;
	std::nth_element(v.begin(), v.begin() + m, v.end());
	return v[m];
}

/** Least-squares line y = a + b*x; false if x is constant. */
bool fitLine(const std::vector<double>& x, const std::vector<double>& y,
             double& a, double& b)
{
	const size_t n = x.size();
	if (n < 2) return false;
	double mx = 0, my = 0;
	for (size_t i = 0; i < n; i++)
	{
		mx += x[i];
		my += y[i];
	}
	mx /= n;
	my /= n;
	double sxx = 0, sxy = 0;
	for (size_t i = 0; i < n; i++)
	{
		sxx += (x[i] - mx) * (x[i] - mx);
		sxy += (x[i] - mx) * (y[i] - my);
	}
	if (sxx <= 0) return false;
	b = sxy / sxx;
	a = my - b * mx;
	return true;
}
}  // namespace

RingOrder parseRingOrder(const std::string& s)
{
	for (auto r :
	     {RingOrder::Auto, RingOrder::Native, RingOrder::ElevationAscending,
	      RingOrder::ElevationDescending})
		if (s == ringOrderName(r)) return r;
	throw std::invalid_argument("ring order '" + s +
	                            "' is not one of auto, native, "
	                            "elevation_ascending, elevation_descending");
}

const char* ringOrderName(RingOrder r)
{
	switch (r)
	{
		case RingOrder::Auto:
			return "auto";
		case RingOrder::Native:
			return "native";
		case RingOrder::ElevationAscending:
			return "elevation_ascending";
		case RingOrder::ElevationDescending:
			return "elevation_descending";
	}
	return "?";
}

ScanOrganizer::ScanOrganizer(const OrganizerOptions& opts)
    : opts_(opts),
      model_(&core::lidarModelByName(opts.lidar_model)),
      ring_order_(opts.ring_order)
{
	if (!(opts_.range_resolution_m > 0))
		throw std::invalid_argument("range_resolution_m must be > 0");
	if (!(opts_.rate_hz > 0))
		throw std::invalid_argument("rate_hz must be > 0");
	const size_t n = model_->rings();
	const auto by_el = model_->rowsByElevation();
	row_of_ring_.resize(n);
	for (size_t r = 0; r < n; r++)
	{
		switch (ring_order_)
		{
			case RingOrder::ElevationAscending:
				row_of_ring_[r] = by_el[r];
				break;
			case RingOrder::ElevationDescending:
				row_of_ring_[r] = by_el[n - 1 - r];
				break;
			default:
				row_of_ring_[r] = static_cast<int>(r);
		}
	}
}

void ScanOrganizer::resolveRingOrder(const std::vector<CloudPoint>& pts)
{
	const size_t n = model_->rings();
	std::vector<std::vector<double>> el(n);
	for (const auto& p : pts)
	{
		const double r = std::sqrt(double(p.x) * p.x + double(p.y) * p.y +
		                           double(p.z) * p.z);
		if (p.ring < n && r > 0) el[p.ring].push_back(std::asin(p.z / r));
	}
	std::vector<double> med(n, std::nan(""));
	size_t present = 0;
	for (size_t r = 0; r < n; r++)
		if (el[r].size() >= 5)
		{
			med[r] = median(el[r]);
			present++;
		}
	if (present < std::min<size_t>(3, n))
	{
		core::logOnce(core::LogLevel::Warn, "ring-order-undecided",
		              "too few points per ring to check the ring order against "
		              "lidar model " +
		                  model_->name + " yet; using native order");
		return;
	}
	const auto by_el = model_->rowsByElevation();
	double best_err = 1e9;
	RingOrder best = RingOrder::Native;
	for (auto cand : {RingOrder::Native, RingOrder::ElevationAscending,
	                  RingOrder::ElevationDescending})
	{
		double se = 0;
		for (size_t r = 0; r < n; r++)
		{
			if (std::isnan(med[r])) continue;
			const int row = cand == RingOrder::Native ? static_cast<int>(r)
			                : cand == RingOrder::ElevationAscending
			                    ? by_el[r]
			                    : by_el[n - 1 - r];
			const double d = med[r] - model_->elevation_rad[row];
			se += d * d;
		}
		const double rms = std::sqrt(se / present);
		if (rms < best_err)
		{
			best_err = rms;
			best = cand;
		}
	}
	// Nominal tables match real units within a few tenths of a degree; a
	// larger misfit means the configured lidar model is wrong.
	constexpr double kMaxRmsRad = 1.5 * M_PI / 180;
	if (best_err > kMaxRmsRad)
		throw std::runtime_error(
		    "the elevations of the cloud's rings do not fit lidar model " +
		    model_->name + " in any ring order (best: " + ringOrderName(best) +
		    ", RMS " + std::to_string(best_err * 180 / M_PI) +
		    " deg): check lidar_model");
	ring_order_ = best;
	for (size_t r = 0; r < n; r++)
		row_of_ring_[r] = best == RingOrder::Native ? static_cast<int>(r)
		                  : best == RingOrder::ElevationAscending
		                      ? by_el[r]
		                      : by_el[n - 1 - r];
	FS_LOG_INFO("ring order of the cloud vs lidar model "
	            << model_->name << ": " << ringOrderName(best)
	            << " (elevation RMS " << best_err * 180 / M_PI << " deg)");
}

void ScanOrganizer::organize(const std::vector<CloudPoint>& pts,
                             int64_t stamp_ns, bool has_time,
                             mrpt::obs::CObservationRotatingScan& out,
                             OrganizeStats* stats)
{
	const size_t rings = model_->rings();
	for (size_t i = 0; i < pts.size(); i++)
		if (pts[i].ring >= rings)
			throw std::runtime_error(
			    "point " + std::to_string(i) + " has ring " +
			    std::to_string(pts[i].ring) + " but lidar model " +
			    model_->name + " has " + std::to_string(rings) + " rings");
	if (ring_order_ == RingOrder::Auto && !pts.empty()) resolveRingOrder(pts);

	OrganizeStats st;
	st.points_in = pts.size();
	out.rowCount = static_cast<uint16_t>(rings);
	out.lidarModel = model_->name;
	out.rangeResolution = opts_.range_resolution_m;
	out.minRange =
	    opts_.min_range_m > 0 ? opts_.min_range_m : model_->min_range_m;
	out.maxRange =
	    opts_.max_range_m > 0 ? opts_.max_range_m : model_->max_range_m;
	out.rangeOtherLayers.clear();
	out.has_satellite_timestamp = false;
	if (pts.empty())
	{
		out.columnCount = 0;
		out.rangeImage.setZero(rings, 0);
		out.intensityImage.setZero(rings, 0);
		out.startAzimuth = 0;
		out.azimuthSpan = 0;
		out.sweepDuration = 0;
		out.timestamp = fromUnixNs(stamp_ns);
		if (stats) *stats = st;
		return;
	}

	// Firing order: by time when known, else the cloud's own order (drivers
	// emit points as they fire, organized clouds row by row).
	std::vector<size_t> order(pts.size());
	std::iota(order.begin(), order.end(), 0);
	if (has_time)
		std::stable_sort(order.begin(), order.end(),
		                 [&](size_t a, size_t b)
		                 { return pts[a].t_s < pts[b].t_s; });
	std::vector<double> az(pts.size());
	for (size_t i = 0; i < pts.size(); i++)
		az[i] = std::atan2(pts[i].y, pts[i].x);

	// Per ring: signed azimuth steps between consecutive returns.
	std::vector<int64_t> prev(rings, -1);
	std::vector<double> first_t(rings, 0), ring_sum(rings, 0), last_t(rings, 0);
	std::vector<double> small_steps;
	double total = 0;
	for (size_t k : order)
	{
		const uint16_t r = pts[k].ring;
		if (prev[r] >= 0)
		{
			const double d = wrapPi(az[k] - az[prev[r]]);
			total += d;
			ring_sum[r] += d;
			if (std::abs(d) > 1e-6 && std::abs(d) < 0.1)
				small_steps.push_back(std::abs(d));
		}
		else
			first_t[r] = pts[k].t_s;
		last_t[r] = pts[k].t_s;
		prev[r] = static_cast<int64_t>(k);
	}
	int s = opts_.rotation_sign;
	if (s == 0) s = total > 0.1 ? +1 : -1;
	double step = median(small_steps);
	if (!(step > 0)) step = model_->azimuth_step_rad;

	// Sweep angle u (radians turned since the first firing) for each point:
	// its azimuth, plus the whole turns predicted by time (or, without time,
	// by the running unwrap of its ring).
	const size_t i0 = order.front();
	const double az0 = az[i0], t0 = pts[i0].t_s;
	std::vector<double> predicted(pts.size());
	if (has_time)
	{
		double du = 0, dt = 0;
		for (size_t r = 0; r < rings; r++)
			if (last_t[r] > first_t[r])
			{
				du += s * ring_sum[r];
				dt += last_t[r] - first_t[r];
			}
		double omega = dt > 0 ? du / dt : 0;
		if (!(du > 0.5) || !(omega > 0)) omega = kTwoPi * opts_.rate_hz;
		for (size_t k = 0; k < pts.size(); k++)
			predicted[k] = omega * (pts[k].t_s - t0);
	}
	else
	{
		std::vector<double> run(rings, 0);
		std::fill(prev.begin(), prev.end(), -1);
		for (size_t k : order)
		{
			const uint16_t r = pts[k].ring;
			run[r] = prev[r] < 0 ? wrapPi(s * (az[k] - az0))
			                     : run[r] + s * wrapPi(az[k] - az[prev[r]]);
			predicted[k] = run[r];
			prev[r] = static_cast<int64_t>(k);
		}
	}
	std::vector<double> u(pts.size());
	double u_min = 1e300;
	for (size_t k = 0; k < pts.size(); k++)
	{
		const double base = s * wrapPi(az[k] - az0);
		u[k] = base + kTwoPi * std::round((predicted[k] - base) / kTwoPi);
		u_min = std::min(u_min, u[k]);
	}

	// Grid: provisional columns from the median step, then spacing and phase
	// refined by least squares so that a cloud made from a range image
	// reproduces that image's grid.
	std::vector<double> col(pts.size());
	for (size_t k = 0; k < pts.size(); k++)
		col[k] = std::round((u[k] - u_min) / step);
	double a = u_min, b = step;
	if (fitLine(col, u, a, b) && std::abs(b - step) < 0.2 * step)
		step = b;
	else
		a = u_min;
	double cmin = 1e300, cmax = -1e300;
	for (size_t k = 0; k < pts.size(); k++)
	{
		col[k] = std::round((u[k] - a) / step);
		cmin = std::min(cmin, col[k]);
		cmax = std::max(cmax, col[k]);
	}
	a += cmin * step;
	const double ncols = cmax - cmin + 1;
	if (ncols > 65535)
		throw std::runtime_error("the cloud spans " + std::to_string(ncols) +
		                         " columns of " +
		                         std::to_string(step * 180 / M_PI) +
		                         " deg: more than a range image can hold (is "
		                         "it several revolutions?)");
	const int n = static_cast<int>(ncols);
	for (auto& c : col) c -= cmin;

	// Column times: t = tau0 + dt_col * c fitted to the points' own times.
	double tau0 = 0, dt_col = step / (kTwoPi * opts_.rate_hz);
	if (has_time)
	{
		std::vector<double> t(pts.size());
		for (size_t k = 0; k < pts.size(); k++) t[k] = pts[k].t_s;
		double fa, fb;
		if (fitLine(col, t, fa, fb) && fb > 0)
		{
			tau0 = fa;
			dt_col = fb;
		}
		else
			tau0 = median(t);
	}

	out.columnCount = static_cast<uint16_t>(n);
	out.startAzimuth = az0 + s * a;
	out.azimuthSpan = n > 1 ? s * step * (n - 1) : 0;
	out.sweepDuration = n > 1 ? dt_col * (n - 1) : 0;
	out.timestamp = fromUnixNs(stamp_ns + std::llround(tau0 * 1e9));
	out.rangeImage.setZero(rings, n);
	out.intensityImage.setZero(rings, n);
	const double max_raw = 65535;
	for (size_t k : order)
	{
		const auto& p = pts[k];
		const double r = std::sqrt(double(p.x) * p.x + double(p.y) * p.y +
		                           double(p.z) * p.z);
		const double raw = std::round(r / opts_.range_resolution_m);
		if (r < out.minRange || r > out.maxRange || raw < 1 || raw > max_raw)
		{
			st.out_of_range++;
			continue;
		}
		int c = static_cast<int>(col[k]);
		const int row = row_of_ring_[p.ring];
		if (out.rangeImage(row, c) != 0)
		{
			// Lasers fire at slightly different azimuths within a column;
			// with jitter two returns of one ring can round to the same
			// column. The neighbour on the return's side is then the better
			// home, if free.
			const double resid = (u[k] - a) / step - c;
			const int c2 = c + (resid >= 0 ? 1 : -1);
			if (c2 < 0 || c2 >= n || out.rangeImage(row, c2) != 0)
			{
				st.collisions++;
				continue;
			}
			c = c2;
		}
		out.rangeImage(row, c) = static_cast<uint16_t>(raw);
		out.intensityImage(row, c) = static_cast<uint8_t>(
		    std::clamp(std::round(double(p.intensity)), 0.0, 255.0));
		st.points_out++;
		if (has_time)
			st.max_time_error_s = std::max(
			    st.max_time_error_s, std::abs(p.t_s - (tau0 + dt_col * c)));
	}
	if (stats) *stats = st;
}

}  // namespace forest_slam::ingest
