#include <forest_slam/core/config.h>
#include <forest_slam/pipeline/pipeline_options.h>

namespace forest_slam::pipeline
{
void PipelineOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                         const std::string& s)
{
	FS_LOAD(c, s, lidar_label);
	FS_LOAD(c, s, imu_label);
	FS_LOAD(c, s, gnss_label);
	FS_LOAD(c, s, pose_source);
	FS_LOAD(c, s, max_scans);
	FS_LOAD(c, s, min_range_m);
	FS_LOAD(c, s, max_range_m);
	FS_LOAD(c, s, deskew);
	FS_LOAD(c, s, gnss_max_speed_mps);
	FS_LOAD(c, s, gnss_jump_tolerance_m);
	FS_LOAD(c, s, memory_report_period_s);
	const std::string where = core::configOrigin(c) + ": [" + s + "] ";
	if (pose_source != "static" && pose_source != "trajectory" &&
		pose_source != "odometry")
		throw core::ConfigError(where +
		                        "pose_source: expected 'odometry', 'static' or "
		                        "'trajectory', got '" +
		                        pose_source + "'");
	if (lidar_label.empty())
		throw core::ConfigError(where + "lidar_label must not be empty");
	if (!(min_range_m >= 0) || !(max_range_m > min_range_m))
		throw core::ConfigError(where + "need 0 <= min_range_m < max_range_m");
	if (!(gnss_max_speed_mps > 0) || !(gnss_jump_tolerance_m > 0))
		throw core::ConfigError(
		    where +
		    "gnss_max_speed_mps and gnss_jump_tolerance_m: expected > 0");
	if (!(memory_report_period_s >= 0))
		throw core::ConfigError(
		    where + "memory_report_period_s: expected >= 0 (0 = off)");
}

void PipelineOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                       const std::string& s) const
{
	c.write(s, "lidar_label", lidar_label);
	c.write(s, "imu_label", imu_label);
	c.write(s, "gnss_label", gnss_label);
	c.write(s, "pose_source", pose_source);
	c.write(s, "max_scans", static_cast<uint64_t>(max_scans));
	c.write(s, "min_range_m", min_range_m);
	c.write(s, "max_range_m", max_range_m);
	c.write(s, "deskew", deskew);
	c.write(s, "gnss_max_speed_mps", gnss_max_speed_mps);
	c.write(s, "gnss_jump_tolerance_m", gnss_jump_tolerance_m);
	c.write(s, "memory_report_period_s", memory_report_period_s);
}

PoseSource PipelineOptions::poseSource() const
{
	if (pose_source == "trajectory") return PoseSource::Trajectory;
	if (pose_source == "odometry") return PoseSource::Odometry;
	return PoseSource::Static;
}

}  // namespace forest_slam::pipeline
