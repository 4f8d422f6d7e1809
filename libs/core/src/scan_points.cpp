#include <forest_slam/core/scan_points.h>

#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/system/datetime.h>

#include <cmath>
#include <stdexcept>

namespace forest_slam::core
{
const std::vector<uint16_t>* ScanPoints::layer(const std::string& name) const
{
	for (const auto& l : layers)
		if (l.first == name) return &l.second;
	return nullptr;
}

double columnAzimuth(const mrpt::obs::CObservationRotatingScan& s, int c)
{
	const int n = s.columnCount;
	return n > 1 ? s.startAzimuth + s.azimuthSpan * c / (n - 1) : s.startAzimuth;
}

double columnTime(const mrpt::obs::CObservationRotatingScan& s, int c)
{
	const int n = s.columnCount;
	return n > 1 ? s.sweepDuration * c / (n - 1) : 0.0;
}

ScanPoints unpackRotatingScan(const mrpt::obs::CObservationRotatingScan& s)
{
	return unpackRotatingScan(s, lidarModelByName(s.lidarModel));
}

ScanPoints unpackRotatingScan(
	const mrpt::obs::CObservationRotatingScan& s, const LidarModel& model)
{
	if (s.rowCount != model.rings())
		throw std::invalid_argument(
			"rotating scan has " + std::to_string(s.rowCount) +
			" rows but lidar model '" + model.name + "' has " +
			std::to_string(model.rings()) + " rings");
	if (static_cast<size_t>(s.rangeImage.rows()) != s.rowCount ||
		static_cast<size_t>(s.rangeImage.cols()) != s.columnCount)
		throw std::invalid_argument(
			"rotating scan range image is " +
			std::to_string(s.rangeImage.rows()) + "x" +
			std::to_string(s.rangeImage.cols()) + ", header says " +
			std::to_string(s.rowCount) + "x" + std::to_string(s.columnCount));
	const bool has_int = s.intensityImage.rows() == s.rowCount &&
						 s.intensityImage.cols() == s.columnCount;

	ScanPoints out;
	out.stamp_s = mrpt::Clock::toDouble(s.timestamp);
	out.sweep_s = s.sweepDuration;
	out.points.reserve(static_cast<size_t>(s.rowCount) * s.columnCount / 2);
	std::vector<const mrpt::math::CMatrix_u16*> layer_src;
	for (const auto& [name, m] : s.rangeOtherLayers)
		if (m.rows() == s.rowCount && m.cols() == s.columnCount)
		{
			out.layers.emplace_back(name, std::vector<uint16_t>{});
			layer_src.push_back(&m);
		}

	std::vector<double> cos_el(s.rowCount), sin_el(s.rowCount);
	for (int r = 0; r < s.rowCount; r++)
	{
		cos_el[r] = std::cos(model.elevation_rad[r]);
		sin_el[r] = std::sin(model.elevation_rad[r]);
	}
	for (int c = 0; c < s.columnCount; c++)
	{
		const double az = columnAzimuth(s, c);
		const double ca = std::cos(az), sa = std::sin(az);
		const float t = static_cast<float>(columnTime(s, c));
		for (int r = 0; r < s.rowCount; r++)
		{
			const uint16_t raw = s.rangeImage(r, c);
			if (raw == 0) continue;
			const double range = raw * s.rangeResolution;
			if (!std::isfinite(range) || range < s.minRange || range > s.maxRange)
				continue;
			ScanPoint p;
			p.range_m = static_cast<float>(range);
			p.x = static_cast<float>(range * cos_el[r] * ca);
			p.y = static_cast<float>(range * cos_el[r] * sa);
			p.z = static_cast<float>(range * sin_el[r]);
			p.intensity = has_int ? s.intensityImage(r, c) : 0.f;
			p.t_s = t;
			p.ring = static_cast<uint16_t>(r);
			p.column = static_cast<uint16_t>(c);
			out.points.push_back(p);
			for (size_t l = 0; l < layer_src.size(); l++)
				out.layers[l].second.push_back((*layer_src[l])(r, c));
		}
	}
	return out;
}

}  // namespace forest_slam::core
