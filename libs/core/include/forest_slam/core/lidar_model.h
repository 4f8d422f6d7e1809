#pragma once
// Beam geometry of spinning lidars. MRPT 2.5's CObservationRotatingScan stores
// an organized range image but no per-ring elevation; we look it up from
// `lidarModel`. Row r of the range image is laser id r in the sensor's native
// order (the order MRPT's fromVelodyne() uses), not sorted by elevation.
#include <string>
#include <vector>

namespace forest_slam::core
{
struct LidarModel
{
	std::string name;  ///< as written in CObservationRotatingScan::lidarModel
	std::vector<double> elevation_rad;	///< per row (laser id)
	double default_rate_hz = 10.0;
	double azimuth_step_rad = 0.0;	///< at default rate
	double min_range_m = 0.5, max_range_m = 100.0;
	double range_noise_m = 0.03;  ///< 1-sigma, datasheet figure
	size_t rings() const { return elevation_rad.size(); }
	/** Rows sorted by increasing elevation (for neighbour-ring searches). */
	std::vector<int> rowsByElevation() const;
};

/** Known models: "VLP16", "HDL32", "OS1-64". Also accepts MRPT/ROS aliases
 * ("VLP-16", "HDL-32E", "OS1_64", case-insensitive). Throws
 * std::invalid_argument listing the known names if `name` is unknown. */
const LidarModel& lidarModelByName(const std::string& name);
/** Null if unknown (no throw). */
const LidarModel* findLidarModel(const std::string& name);
std::vector<std::string> knownLidarModels();

}  // namespace forest_slam::core
