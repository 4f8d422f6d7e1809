#pragma once
// bag2rawlog's engine: ROS bag (1 or 2) -> MRPT rawlog, streaming. Lidar
// (PointCloud2 or velodyne_msgs/VelodyneScan), IMU and GNSS topics become
// observations labelled as the mapping INIs expect ("lidar", "imu", "gnss"
// by default), each with its sensorPose on the vehicle frame from /tf_static
// when the bag has the sensor's frame there, else from the INI.
#include <forest_slam/ingest/bag_reader.h>

#include <mrpt/config/CLoadableOptions.h>

#include <cstdint>
#include <map>
#include <ostream>
#include <string>
#include <vector>

namespace forest_slam::ingest
{
/** Topic, label, frame and fallback extrinsics of one sensor. */
struct SensorTopicOptions : public mrpt::config::CLoadableOptions
{
	std::string topic;  ///< empty: sensor not converted
	std::string sensor_label;
	/** Frame looked up in /tf_static; empty = the messages' header.frame_id. */
	std::string frame_id;
	/** Sensor pose on the vehicle (base) frame when /tf_static lacks it. */
	double pose_x_m = 0, pose_y_m = 0, pose_z_m = 0;
	double pose_yaw_deg = 0, pose_pitch_deg = 0, pose_roll_deg = 0;

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

struct LidarTopicOptions : public SensorTopicOptions
{
	/** core::LidarModel name; "auto" for velodyne packets (from the packets'
	 * model byte). */
	std::string lidar_model = "VLP16";
	/** PointCloud2 output: auto (RotatingScan if the cloud has rings, else
	 * PointCloud), CObservationRotatingScan, CObservationPointCloud. */
	std::string cloud_output = "auto";
	std::string ring_field = "auto", time_field = "auto",
	            intensity_field = "auto";
	std::string time_encoding = "auto";
	std::string ring_order = "auto";
	double range_resolution_m = 0.002;
	/** Revolutions per second, used only for clouds without per-point time. */
	double rate_hz = 10.0;
	std::string rotation = "auto";            ///< auto, cw, ccw
	double min_range_m = 0, max_range_m = 0;  ///< 0: lidar model's
	/** velodyne_msgs/VelodyneScan: calibration (ROS YAML or Velodyne XML);
	 * empty = MRPT's default for the model. */
	std::string calibration_file;
	/** CObservationVelodyneScan (raw packets + calibration) or
	 * CObservationRotatingScan (decoded, what the mapping pipeline reads). */
	std::string velodyne_output = "CObservationVelodyneScan";
	std::string dual_return = "strongest";

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

struct Bag2RawlogOptions : public mrpt::config::CLoadableOptions
{
	/** The vehicle frame sensor poses refer to. */
	std::string base_frame = "base_link";
	bool use_tf_static = true;
	std::string tf_static_topic = "/tf_static";
	int compress_level = 1;  ///< gzip level of the output rawlog (0..9)
	LidarTopicOptions lidar;
	SensorTopicOptions imu, gnss;

	Bag2RawlogOptions();
	/** Sections [bag2rawlog], [bag2rawlog_lidar], [bag2rawlog_imu],
	 * [bag2rawlog_gnss]; `s` is ignored. Throws core::ConfigError. */
	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s = "") override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s = "") const override;
};

struct TopicReport
{
	std::string role;  ///< lidar, imu, gnss, tf_static
	std::string topic, type, label;
	uint64_t messages_in = 0, observations_out = 0;
	std::map<std::string, uint64_t> skipped;  ///< reason -> count
	std::string pose_source;  ///< "/tf_static (velodyne -> base_link)" / "INI"
	std::string detail;       ///< e.g. the PointCloud2 layout found
};

struct ConversionReport
{
	std::vector<TopicReport> topics;
	uint64_t observations_written = 0;
	/** Empty on success; else what stopped the conversion. The output then
	 * holds every observation converted before the problem. */
	std::string error;
	bool ok() const { return error.empty(); }
};

/** Any problem found before writing (config vs bag); nothing is written. */
class ConversionSetupError : public std::runtime_error
{
   public:
	using std::runtime_error::runtime_error;
};

/** Converts `bag_path` into `rawlog_path` (written atomically). Throws
 * ConversionSetupError for configuration/bag mismatches found before
 * writing; problems in the middle of the bag end the conversion with
 * report.error set and the output committed. */
ConversionReport convertBag(const std::string& bag_path,
                            const std::string& rawlog_path,
                            const Bag2RawlogOptions& opts,
                            bool show_progress = true);

/** `--list`: topics, types, counts, rates. */
void printTopicList(const BagReader& bag, std::ostream& os);
/** The final per-topic summary. */
void printReport(const ConversionReport& r, std::ostream& os);

}  // namespace forest_slam::ingest
