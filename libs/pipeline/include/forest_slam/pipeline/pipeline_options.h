#pragma once
// [pipeline] section: which observations feed which stage, and where poses
// come from until (and besides) the odometry stage.
#include <mrpt/config/CLoadableOptions.h>

#include <string>

namespace forest_slam::pipeline
{
enum class PoseSource
{
	Static,		///< the sensor did not move (tripod / TLS-like scanning)
	Trajectory,	 ///< poses interpolated from a TUM file (--poses)
	Odometry	///< lidar odometry and mapping (libs/odometry)
};

struct PipelineOptions : public mrpt::config::CLoadableOptions
{
	std::string lidar_label = "lidar";	///< sensorLabel of lidar scans
	std::string imu_label = "imu";
	std::string gnss_label = "gnss";
	/** "odometry" (lidar odometry), "static" or "trajectory" (needs
	 * `forest-slam map --poses FILE`). */
	std::string pose_source = "odometry";
	uint64_t max_scans = 0;	 ///< stop after this many scans (0 = all)
	double min_range_m = 0.8;  ///< drop returns closer (operator, robot body)
	double max_range_m = 80.0;
	/** Deskew: move every point with the pose at its own firing time. */
	bool deskew = true;
	/** GNSS fixes farther from the last accepted fix than
	 * gnss_max_speed_mps * dt + gnss_jump_tolerance_m are jumps: logged and
	 * not used (doc/reliability.md). */
	double gnss_max_speed_mps = 20.0;
	double gnss_jump_tolerance_m = 20.0;
	/** Every this many seconds of data the run logs its memory (RSS and
	 * the big containers) and adds a point to run_summary.json's memory
	 * curve; 0 = only at the end. */
	double memory_report_period_s = 300.0;

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
							const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
						  const std::string& section) const override;
	PoseSource poseSource() const;
};

}  // namespace forest_slam::pipeline
