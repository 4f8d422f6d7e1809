#include <forest_slam/online/online_config.h>

#include <mrpt/core/bits_math.h>
#include <mrpt/hwdrivers/CVelodyneScanner.h>

#include <algorithm>

namespace forest_slam::online
{
void OnlineOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                       const std::string& s)
{
	FS_LOAD(c, s, light_above_queued_scans);
	FS_LOAD(c, s, queue_capacity_scans);
	FS_LOAD(c, s, status_period_s);
	FS_LOAD(c, s, record_compress_level);
	FS_LOAD(c, s, record_flush_period_s);
	FS_LOAD(c, s, idle_timeout_s);
	const std::string where = core::configOrigin(c) + ": [" + s + "] ";
	if (queue_capacity_scans < 1 ||
	    light_above_queued_scans >= queue_capacity_scans)
		throw core::ConfigError(
		    where +
		    "need 0 <= light_above_queued_scans < queue_capacity_scans");
	if (record_compress_level < 0 || record_compress_level > 9)
		throw core::ConfigError(where +
		                        "record_compress_level: expected 0..9, got " +
		                        std::to_string(record_compress_level));
	if (!(status_period_s >= 0) || !(record_flush_period_s > 0) ||
	    !(idle_timeout_s >= 0))
		throw core::ConfigError(
		    where +
		    "status_period_s and idle_timeout_s must be >= 0, "
		    "record_flush_period_s > 0");
}

void OnlineOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                     const std::string& s) const
{
	c.write(s, "light_above_queued_scans", light_above_queued_scans);
	c.write(s, "queue_capacity_scans", queue_capacity_scans);
	c.write(s, "status_period_s", status_period_s);
	c.write(s, "record_compress_level", record_compress_level);
	c.write(s, "record_flush_period_s", record_flush_period_s);
	c.write(s, "idle_timeout_s", idle_timeout_s);
}

namespace
{
/** Our receiver's settings from the driver's configuration. */
std::shared_ptr<VelodyneUdpSettings> velodyneUdpSettings(
    const mrpt::config::CConfigFileBase& cfg, const std::string& sec,
    const SensorDeclaration& d, const OnlineConfig& out)
{
	using mrpt::hwdrivers::CVelodyneScanner;
	const auto& v = dynamic_cast<const CVelodyneScanner&>(*d.sensor);
	auto s = std::make_shared<VelodyneUdpSettings>();
	s->label = d.label;
	s->device_ip = v.getDeviceIP();
	s->data_port = out.velodyne_data_port;
	s->position_port = out.velodyne_position_port;
	s->pos_packets_min_period_s = v.getPosPacketsMinPeriod();
	s->pos_packets_timing_timeout_s = v.getPosPacketsTimingTimeout();
	const std::string model =
	    mrpt::typemeta::TEnumType<CVelodyneScanner::model_t>::value2name(
	        v.getModelName());
	s->calibration = v.getCalibration();
	if (s->calibration.empty())
		s->calibration =
		    mrpt::obs::VelodyneCalibration::LoadDefaultCalibration(model);
	if (s->calibration.empty())
		throw core::ConfigError(core::configOrigin(cfg) + ": [" + sec +
		                        "] no calibration for model " + model +
		                        " (set calibration_file)");
	const auto& props = CVelodyneScanner::TModelPropertiesFactory::get();
	if (const auto it = props.find(v.getModelName()); it != props.end())
		s->max_range_m = it->second.maxRange;
	s->sensor_pose = mrpt::poses::CPose3D(
	    cfg.read_double(sec, "pose_x", 0), cfg.read_double(sec, "pose_y", 0),
	    cfg.read_double(sec, "pose_z", 0),
	    mrpt::DEG2RAD(cfg.read_double(sec, "pose_yaw", 0)),
	    mrpt::DEG2RAD(cfg.read_double(sec, "pose_pitch", 0)),
	    mrpt::DEG2RAD(cfg.read_double(sec, "pose_roll", 0)));
	return s;
}

SensorDeclaration loadSensor(core::TrackedConfig& cfg, const std::string& sec,
                             OnlineConfig& out)
{
	const std::string where = cfg.origin() + ": [" + sec + "] ";
	SensorDeclaration d;
	d.section = sec;
	d.driver = cfg.read_string(sec, "driver", "");
	d.sensor = mrpt::hwdrivers::CGenericSensor::createSensorPtr(d.driver);
	if (!d.sensor)
		throw core::ConfigError(
		    where + "driver = " + d.driver +
		    ": not a sensor driver of this MRPT build (e.g. CVelodyneScanner, "
		    "CIMUXSens_MT4, CIMUIntersense, CGPSInterface, CGPS_NTRIP)");
	// The driver reads its own keys through the tracked config, so the
	// strict check below knows exactly which keys it uses.
	try
	{
		d.sensor->loadConfig(cfg, sec);
	}
	catch (const std::exception& e)
	{
		std::string what = e.what();
		if (what.size() > 400) what = what.substr(0, 400) + "...";
		throw core::ConfigError(where + "driver " + d.driver +
		                        " rejected its configuration: " + what);
	}
	d.process_rate_hz = d.sensor->getProcessRate();
	if (!(d.process_rate_hz > 0))
		throw core::ConfigError(where +
		                        "process_rate: required (Hz, > 0), as in "
		                        "rawlog-grabber (CVelodyneScanner: ~2000, to "
		                        "poll every packet)");
	d.label = d.sensor->getSensorLabel();
	if (d.driver == "CVelodyneScanner")
	{
		// MRPT 2.5.8 labels scans "<label>_SCAN" and position packets
		// "<label>_GPS".
		d.output_labels = {d.label + "_SCAN", d.label + "_GPS"};
		d.replays_file = !cfg.read_string(sec, "pcap_input", "").empty();
		core::loadOption(cfg, sec, "udp_data_port", out.velodyne_data_port);
		core::loadOption(cfg, sec, "udp_position_port",
		                 out.velodyne_position_port);
		for (int port : {out.velodyne_data_port, out.velodyne_position_port})
			if (port < 1 || port > 65535)
				throw core::ConfigError(where +
				                        "udp_data_port / udp_position_port: "
				                        "expected 1..65535, got " +
				                        std::to_string(port));
		std::string receiver = "forest-slam";
		core::loadOption(cfg, sec, "udp_receiver", receiver);
		if (receiver != "forest-slam" && receiver != "mrpt")
			throw core::ConfigError(
			    where + "udp_receiver: expected forest-slam or mrpt, got '" +
			    receiver + "'");
		if (receiver == "forest-slam" && !d.replays_file)
			d.velodyne_udp = velodyneUdpSettings(cfg, sec, d, out);
	}
	else
		d.output_labels = {d.label};
	return d;
}
}  // namespace

OnlineConfig OnlineConfig::loadFile(const std::string& path)
{
	auto cfg = core::TrackedConfig::fromFile(path);
	OnlineConfig oc;
	std::vector<std::string> sections;
	cfg.getAllSections(sections);
	int velodynes = 0;
	for (const auto& sec : sections)
	{
		// Look without reading: a read would mark any section as known.
		std::vector<std::string> keys;
		cfg.getAllKeys(sec, keys);
		if (!std::count(keys.begin(), keys.end(), std::string("driver")))
			continue;
		oc.sensors.push_back(loadSensor(cfg, sec, oc));
		velodynes += oc.sensors.back().driver == "CVelodyneScanner";
	}
	if (velodynes > 1)
		throw core::ConfigError(
		    path +
		    ": more than one CVelodyneScanner section: "
		    "MRPT's driver binds the same UDP ports for all");
	oc.online.loadFromConfigFile(cfg, "online");
	{
		// Strict check of the sensor sections and [online] (MappingConfig
		// accepts them wholesale, for offline re-runs with the same INI).
		core::TrackedConfig check = cfg;
		for (const auto& sec : sections)
		{
			const bool sensor = std::any_of(
			    oc.sensors.begin(), oc.sensors.end(),
			    [&](const SensorDeclaration& d) { return d.section == sec; });
			if (!sensor && sec != "online") check.acceptSection(sec);
		}
		check.checkNoUnknownKeys();
	}
	oc.mapping = pipeline::MappingConfig::load(cfg);

	if (oc.sensors.empty())
		throw core::ConfigError(
		    path +
		    ": no sensor section (a section with driver = <MRPT class>, "
		    "e.g. [VLP16] driver = CVelodyneScanner; see doc/online.md)");
	std::vector<std::string> all_labels;
	for (const auto& s : oc.sensors)
	{
		for (const auto& l : s.output_labels)
			if (std::count(all_labels.begin(), all_labels.end(), l))
				throw core::ConfigError(
				    path + ": [" + s.section + "] produces label '" + l +
				    "' like another sensor (set sensorLabel)");
		all_labels.insert(all_labels.end(), s.output_labels.begin(),
		                  s.output_labels.end());
	}
	const auto& lidar = oc.mapping.pipeline.lidar_label;
	if (!std::count(all_labels.begin(), all_labels.end(), lidar))
	{
		std::string have;
		for (const auto& l : all_labels) have += (have.empty() ? "" : ", ") + l;
		throw core::ConfigError(
		    path + ": [pipeline] lidar_label = " + lidar +
		    " matches no sensor's observations (the sensors "
		    "produce: " +
		    have +
		    "; CVelodyneScanner appends _SCAN to its "
		    "sensorLabel)");
	}
	return oc;
}

}  // namespace forest_slam::online
