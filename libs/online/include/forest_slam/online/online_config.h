#pragma once
// An online run's INI: the sensors, declared like MRPT's rawlog-grabber does
// (one section per sensor with `driver = <MRPT class>`, `process_rate` and
// the driver's own keys), the [online] section, and every mapping section
// of an offline run. Keys are checked strictly: the driver's keys are those
// the MRPT driver itself reads, so a typo is an error naming the key.
#include <forest_slam/core/config.h>
#include <forest_slam/online/velodyne_udp.h>
#include <forest_slam/pipeline/mapping_config.h>

#include <mrpt/config/CLoadableOptions.h>

#include <memory>
#include <string>
#include <vector>

namespace mrpt::hwdrivers
{
class CGenericSensor;
}

namespace forest_slam::online
{
struct OnlineOptions : public mrpt::config::CLoadableOptions
{
	/** Scans waiting for the pipeline beyond which it goes light: scans get
	 * the motion model's pose, without registration or map insertion, until
	 * it caught up (the raw recording keeps them all). */
	uint64_t light_above_queued_scans = 10;
	/** Scans waiting beyond which the oldest waiting one is dropped from
	 * the pipeline's queue (never from the recording). */
	uint64_t queue_capacity_scans = 300;
	double status_period_s = 1.0;  ///< status line period; 0 = none
	/** raw.rawlog compression: 0 = plain (followable record by record,
	 * crash-safe up to the last flush), 1..9 = gzip level. */
	int record_compress_level = 0;
	double record_flush_period_s = 0.2;  ///< raw.rawlog reaches the disk
	/** End the run after this long without any observation from any sensor
	 * (0 = never; Ctrl-C ends it). */
	double idle_timeout_s = 0;

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& section) const override;
};

/** One sensor section: the MRPT driver, configured, not yet initialized. */
struct SensorDeclaration
{
	std::string section, driver, label;
	double process_rate_hz = 0;
	/** Labels of the observations this sensor produces (CVelodyneScanner:
	 * "<label>_SCAN" and "<label>_GPS"). */
	std::vector<std::string> output_labels;
	bool replays_file = false;  ///< e.g. CVelodyneScanner pcap_input
	/** CVelodyneScanner over UDP with `udp_receiver = forest-slam` (the
	 * default): our receiver replaces the driver's receive loop. */
	std::shared_ptr<VelodyneUdpSettings> velodyne_udp;
	std::shared_ptr<mrpt::hwdrivers::CGenericSensor> sensor;
};

struct OnlineConfig
{
	pipeline::MappingConfig mapping;
	OnlineOptions online;  ///< [online]
	std::vector<SensorDeclaration> sensors;
	/** CVelodyneScanner UDP ports (process-wide in MRPT): the Velodyne
	 * section's optional udp_data_port / udp_position_port. */
	int velodyne_data_port = 2368, velodyne_position_port = 8308;

	/** Throws core::ConfigError naming file, section and key: unknown keys,
	 * unknown drivers, a missing process_rate, pipeline labels no sensor
	 * produces, no sensor at all. */
	static OnlineConfig loadFile(const std::string& path);
};

}  // namespace forest_slam::online
