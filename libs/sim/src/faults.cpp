#include <forest_slam/sim/faults.h>
#include <forest_slam/sim/gnss_sim.h>
#include <forest_slam/sim/imu_sim.h>

#include <mrpt/obs/CObservationRotatingScan.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace forest_slam::sim
{
namespace
{
std::string num(double v)
{
	char buf[64];
	std::snprintf(buf, sizeof(buf), "%.12g", v);
	return buf;
}
#define FS_SAVE_FAULT(cfg, section, field) \
	cfg.write(section, #field, num(field))

/** First sample of a stream (times t_rel) at or after `at`. */
bool firstAtOrAfter(double at, double t_rel, double step)
{
	return at >= 0 && t_rel >= at - 1e-9 && t_rel < at + step - 1e-9;
}
}  // namespace

bool FaultOptions::any() const
{
	return nan_scan_at_s >= 0 || empty_scan_at_s >= 0 || lidar_gap_at_s >= 0 ||
	       imu_gap_at_s >= 0 || imu_backwards_at_s >= 0 ||
	       gnss_jump_at_s >= 0 || duplicate_scan_at_s >= 0 ||
	       open_field_at_s >= 0;
}

void FaultOptions::validate(const std::string& origin) const
{
	auto check = [&](bool ok, const char* key, const char* expected)
	{
		if (!ok)
			throw core::ConfigError(origin + ": [faults] " + key +
			                        ": expected " + expected);
	};
	check(lidar_gap_s > 0 && lidar_gap_s <= 60, "lidar_gap_s", "0..60 s");
	check(imu_gap_s > 0 && imu_gap_s <= 60, "imu_gap_s", "0..60 s");
	check(imu_backwards_s > 0 && imu_backwards_s <= 10, "imu_backwards_s",
	      "0..10 s");
	check(std::isfinite(gnss_jump_m) && std::abs(gnss_jump_m) <= 1e5,
	      "gnss_jump_m", "-1e5..1e5 m");
	check(gnss_jump_duration_s > 0, "gnss_jump_duration_s", "> 0 s");
	check(open_field_s > 0, "open_field_s", "> 0 s");
}

std::vector<std::string> FaultOptions::describe() const
{
	std::vector<std::string> out;
	auto at = [](double t) { return "at " + num(t) + " s"; };
	if (nan_scan_at_s >= 0) out.push_back("NaN scan " + at(nan_scan_at_s));
	if (empty_scan_at_s >= 0)
		out.push_back("empty scan " + at(empty_scan_at_s));
	if (lidar_gap_at_s >= 0)
		out.push_back("lidar gap of " + num(lidar_gap_s) + " s " +
		              at(lidar_gap_at_s));
	if (imu_gap_at_s >= 0)
		out.push_back("IMU gap of " + num(imu_gap_s) + " s " +
		              at(imu_gap_at_s));
	if (imu_backwards_at_s >= 0)
		out.push_back("IMU stamp " + num(imu_backwards_s) + " s backwards " +
		              at(imu_backwards_at_s));
	if (gnss_jump_at_s >= 0)
		out.push_back("GNSS jump of " + num(gnss_jump_m) + " m for " +
		              num(gnss_jump_duration_s) + " s " + at(gnss_jump_at_s));
	if (duplicate_scan_at_s >= 0)
		out.push_back("duplicated scan " + at(duplicate_scan_at_s));
	if (open_field_at_s >= 0)
		out.push_back("open field (ground returns only) for " +
		              num(open_field_s) + " s " + at(open_field_at_s));
	return out;
}

void FaultOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                      const std::string& s)
{
	FS_LOAD(c, s, nan_scan_at_s);
	FS_LOAD(c, s, empty_scan_at_s);
	FS_LOAD(c, s, lidar_gap_at_s);
	FS_LOAD(c, s, lidar_gap_s);
	FS_LOAD(c, s, imu_gap_at_s);
	FS_LOAD(c, s, imu_gap_s);
	FS_LOAD(c, s, imu_backwards_at_s);
	FS_LOAD(c, s, imu_backwards_s);
	FS_LOAD(c, s, gnss_jump_at_s);
	FS_LOAD(c, s, gnss_jump_m);
	FS_LOAD(c, s, gnss_jump_duration_s);
	FS_LOAD(c, s, duplicate_scan_at_s);
	FS_LOAD(c, s, open_field_at_s);
	FS_LOAD(c, s, open_field_s);
}

void FaultOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                    const std::string& s) const
{
	FS_SAVE_FAULT(c, s, nan_scan_at_s);
	FS_SAVE_FAULT(c, s, empty_scan_at_s);
	FS_SAVE_FAULT(c, s, lidar_gap_at_s);
	FS_SAVE_FAULT(c, s, lidar_gap_s);
	FS_SAVE_FAULT(c, s, imu_gap_at_s);
	FS_SAVE_FAULT(c, s, imu_gap_s);
	FS_SAVE_FAULT(c, s, imu_backwards_at_s);
	FS_SAVE_FAULT(c, s, imu_backwards_s);
	FS_SAVE_FAULT(c, s, gnss_jump_at_s);
	FS_SAVE_FAULT(c, s, gnss_jump_m);
	FS_SAVE_FAULT(c, s, gnss_jump_duration_s);
	FS_SAVE_FAULT(c, s, duplicate_scan_at_s);
	FS_SAVE_FAULT(c, s, open_field_at_s);
	FS_SAVE_FAULT(c, s, open_field_s);
}

ScanFault scanFault(const FaultOptions& f, double t, double period)
{
	if (f.lidar_gap_at_s >= 0 && t >= f.lidar_gap_at_s - 1e-9 &&
	    t < f.lidar_gap_at_s + f.lidar_gap_s - 1e-9)
		return ScanFault::Drop;
	if (f.open_field_at_s >= 0 && t >= f.open_field_at_s - 1e-9 &&
	    t < f.open_field_at_s + f.open_field_s - 1e-9)
		return ScanFault::OpenField;
	if (firstAtOrAfter(f.nan_scan_at_s, t, period)) return ScanFault::NonFinite;
	if (firstAtOrAfter(f.empty_scan_at_s, t, period)) return ScanFault::Empty;
	if (firstAtOrAfter(f.duplicate_scan_at_s, t, period))
		return ScanFault::Duplicate;
	return ScanFault::None;
}

void applyScanFault(ScanFault fault, mrpt::obs::CObservationRotatingScan& s)
{
	if (fault == ScanFault::NonFinite)
		s.azimuthSpan = std::numeric_limits<double>::quiet_NaN();
	else if (fault == ScanFault::Empty)
	{
		s.rangeImage.setZero();
		s.intensityImage.setZero();
		for (auto& [name, layer] : s.rangeOtherLayers) layer.setZero();
	}
	else if (fault == ScanFault::OpenField)
	{
		const auto it = s.rangeOtherLayers.find("gt_label");
		if (it == s.rangeOtherLayers.end())
			throw std::invalid_argument(
			    "[faults] open_field_at_s needs [lidar] gt_layers = true");
		constexpr uint16_t kGround = 1;
		const auto& label = it->second;
		for (int r = 0; r < s.rangeImage.rows(); r++)
			for (int c = 0; c < s.rangeImage.cols(); c++)
				if (label(r, c) != kGround)
				{
					s.rangeImage(r, c) = 0;
					if (s.intensityImage.rows() == s.rangeImage.rows() &&
					    s.intensityImage.cols() == s.rangeImage.cols())
						s.intensityImage(r, c) = 0;
					for (auto& [name, layer] : s.rangeOtherLayers)
						if (name != "gt_label") layer(r, c) = 0;
				}
		// Labels last: the loop above reads them.
		for (int r = 0; r < s.rangeImage.rows(); r++)
			for (int c = 0; c < s.rangeImage.cols(); c++)
				if (s.rangeImage(r, c) == 0) it->second(r, c) = 0;
	}
}

void applyImuFaults(const FaultOptions& f, double t0,
                    std::vector<ImuSample>& imu)
{
	if (f.imu_backwards_at_s >= 0)
		for (size_t i = 1; i < imu.size(); i++)
			if (imu[i].t - t0 >= f.imu_backwards_at_s - 1e-9)
			{
				imu[i].t = imu[i - 1].t - f.imu_backwards_s;
				break;
			}
	if (f.imu_gap_at_s >= 0)
	{
		const double a = t0 + f.imu_gap_at_s, b = a + f.imu_gap_s;
		std::vector<ImuSample> kept;
		kept.reserve(imu.size());
		for (const auto& s : imu)
			if (s.t < a - 1e-9 || s.t >= b - 1e-9) kept.push_back(s);
		imu.swap(kept);
	}
}

void applyGnssFaults(const FaultOptions& f, double t0, const GnssOptions& o,
                     std::vector<GnssFix>& gnss)
{
	if (f.gnss_jump_at_s < 0) return;
	const double a = t0 + f.gnss_jump_at_s, b = a + f.gnss_jump_duration_s;
	for (auto& g : gnss)
		if (g.quality > 0 && g.t >= a - 1e-9 && g.t < b - 1e-9)
		{
			g.enu_measured.x() += f.gnss_jump_m;
			enuToGeodetic(g.enu_measured, o, g.lat_deg, g.lon_deg, g.height_m);
		}
}

}  // namespace forest_slam::sim
