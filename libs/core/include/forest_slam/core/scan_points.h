#pragma once
// A rotating scan unpacked into points in the sensor frame, each with its own
// firing time, ring and column: the common input of every front-end stage.
#include <forest_slam/core/lidar_model.h>

#include <cstdint>
#include <string>
#include <vector>

namespace mrpt::obs
{
class CObservationRotatingScan;
}

namespace forest_slam::core
{
struct ScanPoint
{
	float x = 0, y = 0, z = 0;	///< sensor frame [m]
	float range_m = 0;
	float intensity = 0;  ///< 0..255
	float t_s = 0;	///< seconds after the scan timestamp (first firing)
	uint16_t ring = 0;	///< row of the range image (laser id)
	uint16_t column = 0;
};

struct ScanPoints
{
	double stamp_s = 0;	 ///< UNIX seconds of the first firing
	double sweep_s = 0;	 ///< duration of the sweep
	std::vector<ScanPoint> points;
	/** Optional per-point integer layers (e.g. "gt_label", "gt_tree"),
	 * same size as `points` when present. */
	std::vector<std::pair<std::string, std::vector<uint16_t>>> layers;
	const std::vector<uint16_t>* layer(const std::string& name) const;
};

/** Azimuth [rad] and time offset [s] of column `c` of a rotating scan:
 * columns are evenly spaced from startAzimuth to startAzimuth+azimuthSpan and
 * from 0 to sweepDuration (MRPT's documented convention). */
double columnAzimuth(const mrpt::obs::CObservationRotatingScan& s, int c);
double columnTime(const mrpt::obs::CObservationRotatingScan& s, int c);

/** Unpacks every valid return (range != 0, within [minRange,maxRange]).
 * The lidar model comes from `s.lidarModel`; throws std::invalid_argument
 * naming the model if unknown or if rowCount does not match the model. Extra
 * range layers (rangeOtherLayers) are copied as per-point layers. */
ScanPoints unpackRotatingScan(const mrpt::obs::CObservationRotatingScan& s);
ScanPoints unpackRotatingScan(
	const mrpt::obs::CObservationRotatingScan& s, const LidarModel& model);

}  // namespace forest_slam::core
