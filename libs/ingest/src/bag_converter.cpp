#include <forest_slam/core/config.h>
#include <forest_slam/core/lidar_model.h>
#include <forest_slam/core/log.h>
#include <forest_slam/core/progress.h>
#include <forest_slam/ingest/bag_converter.h>
#include <forest_slam/ingest/observations.h>
#include <forest_slam/ingest/pointcloud2.h>
#include <forest_slam/ingest/scan_organizer.h>
#include <forest_slam/ingest/stamps.h>
#include <forest_slam/ingest/tf_static.h>
#include <forest_slam/ingest/velodyne.h>
#include <forest_slam/io/rawlog_writer.h>

#include <mrpt/core/bits_math.h>
#include <mrpt/maps/CColouredPointsMap.h>
#include <mrpt/maps/CPointsMapXYZI.h>
#include <mrpt/obs/CObservationPointCloud.h>

#include <algorithm>
#include <iomanip>
#include <optional>
#include <sstream>

namespace forest_slam::ingest
{
namespace
{
const char* kMain = "bag2rawlog";
const char* kLidar = "bag2rawlog_lidar";
const char* kImu = "bag2rawlog_imu";
const char* kGnss = "bag2rawlog_gnss";

void requireOneOf(const mrpt::config::CConfigFileBase& c, const std::string& s,
                  const char* key, const std::string& v,
                  const std::vector<std::string>& allowed)
{
	if (std::find(allowed.begin(), allowed.end(), v) != allowed.end()) return;
	std::string list;
	for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
	throw core::ConfigError(core::configOrigin(c) + ": [" + s + "] " + key +
	                        " = '" + v + "' is not one of: " + list);
}

mrpt::poses::CPose3D iniPose(const SensorTopicOptions& o)
{
	return mrpt::poses::CPose3D(
	    o.pose_x_m, o.pose_y_m, o.pose_z_m, mrpt::DEG2RAD(o.pose_yaw_deg),
	    mrpt::DEG2RAD(o.pose_pitch_deg), mrpt::DEG2RAD(o.pose_roll_deg));
}

std::string poseText(const mrpt::poses::CPose3D& p)
{
	std::ostringstream os;
	os << std::fixed << std::setprecision(3) << "(x,y,z)=(" << p.x() << ","
	   << p.y() << "," << p.z() << ") m, (yaw,pitch,roll)=("
	   << std::setprecision(2) << mrpt::RAD2DEG(p.yaw()) << ","
	   << mrpt::RAD2DEG(p.pitch()) << "," << mrpt::RAD2DEG(p.roll()) << ") deg";
	return os.str();
}

/** One converted sensor: options, report row, extrinsics once resolved. */
struct Sensor
{
	const SensorTopicOptions* opts = nullptr;
	const char* section = "";
	size_t report_index = 0;
	bool pose_resolved = false;
	mrpt::poses::CPose3D pose;
	std::string frame;
};

class Converter
{
   public:
	Converter(const Bag2RawlogOptions& o, const std::string& bag_path)
	    : opts_(o), bag_path_(bag_path)
	{
	}

	ConversionReport run(const std::string& out_path, bool show_progress);

   private:
	const Bag2RawlogOptions& opts_;
	std::string bag_path_;
	ConversionReport report_;
	std::unique_ptr<BagReader> bag_;
	std::map<std::string, Sensor> sensors_;  ///< by topic
	StaticTransforms tf_;
	bool tf_in_bag_ = false;
	// Lidar state:
	MsgKind lidar_kind_ = MsgKind::Unknown;
	std::optional<ScanOrganizer> organizer_;
	std::optional<VelodyneCalib> velodyne_calib_;
	CloudLayoutOptions layout_opts_;
	bool layout_logged_ = false;
	uint64_t pts_in_ = 0, pts_out_ = 0, pts_range_ = 0, pts_dup_ = 0,
	         pts_invalid_ = 0;
	std::vector<CloudPoint> cloud_pts_;
	std::vector<VelodynePoint> velo_pts_;

	TopicReport& rep(const Sensor& s) { return report_.topics[s.report_index]; }
	void validate();
	void readTfStatic();
	const mrpt::poses::CPose3D& poseOf(Sensor& s,
	                                   const std::string& header_frame);
	void handle(const BagMessage& m, Sensor& s, io::RawlogWriter& w);
	void handleCloud(const BagMessage& m, Sensor& s, io::RawlogWriter& w);
	void handleVelodyne(const BagMessage& m, Sensor& s, io::RawlogWriter& w);
	void finishDetail();
};

void Converter::validate()
{
	auto add = [&](const SensorTopicOptions& o, const char* role,
	               const char* section, std::vector<MsgKind> kinds,
	               bool required)
	{
		if (o.topic.empty()) return;
		const TopicInfo* t = bag_->findTopic(o.topic);
		if (!t)
		{
			std::string have;
			for (const auto& x : bag_->topics())
				have += "\n  " + x.name + " (" + x.type + ")";
			const std::string msg = "bag '" + bag_path_ + "' has no topic '" +
			                        o.topic + "' ([" + section +
			                        "] topic); its topics:" + have;
			if (required) throw ConversionSetupError(msg);
			FS_LOG_WARN(msg << "\n" << role << " is not converted");
			return;
		}
		if (std::find(kinds.begin(), kinds.end(), t->kind) == kinds.end())
		{
			std::string want;
			for (auto k : kinds)
				want += (want.empty() ? "" : " or ") + std::string(kindName(k));
			throw ConversionSetupError("topic " + o.topic + " has type " +
			                           t->type + "; the " + role +
			                           " topic must be " + want);
		}
		if (bag_->format() == BagFormat::Ros1 && !t->md5.empty() &&
		    t->md5 != "*" && t->md5 != ros1Md5(t->kind))
			throw ConversionSetupError(
			    "topic " + o.topic + " is recorded as " + t->type +
			    " with definition md5 " + t->md5 + ", expected " +
			    ros1Md5(t->kind) +
			    ": the message layout differs from the known one");
		if (bag_->format() == BagFormat::Ros2 && t->serialization != "cdr")
			throw ConversionSetupError(
			    "topic " + o.topic + " is serialized as '" + t->serialization +
			    "'; only cdr is supported");
		if (sensors_.count(o.topic))
			throw ConversionSetupError("topic " + o.topic +
			                           " is configured for two sensors");
		Sensor s;
		s.opts = &o;
		s.section = section;
		s.report_index = report_.topics.size();
		TopicReport r;
		r.role = role;
		r.topic = o.topic;
		r.type = t->type;
		r.label = o.sensor_label;
		report_.topics.push_back(r);
		sensors_[o.topic] = s;
		if (std::string(role) == "lidar") lidar_kind_ = t->kind;
	};
	add(opts_.lidar, "lidar", kLidar,
	    {MsgKind::PointCloud2, MsgKind::VelodyneScan}, true);
	add(opts_.imu, "imu", kImu, {MsgKind::Imu}, false);
	add(opts_.gnss, "gnss", kGnss, {MsgKind::NavSatFix}, false);
	if (sensors_.empty())
		throw ConversionSetupError("no topic to convert: set [" +
		                           std::string(kLidar) + "] topic");

	const auto& L = opts_.lidar;
	if (lidar_kind_ == MsgKind::PointCloud2)
	{
		if (L.lidar_model == "auto")
			throw ConversionSetupError(
			    "[" + std::string(kLidar) +
			    "] lidar_model = auto only works for velodyne "
			    "packets; name the model of a PointCloud2 topic");
		OrganizerOptions oo;
		oo.lidar_model = L.lidar_model;
		oo.ring_order = parseRingOrder(L.ring_order);
		oo.range_resolution_m = L.range_resolution_m;
		oo.rate_hz = L.rate_hz;
		oo.rotation_sign = L.rotation == "cw"    ? -1
		                   : L.rotation == "ccw" ? 1
		                                         : 0;
		oo.min_range_m = L.min_range_m;
		oo.max_range_m = L.max_range_m;
		organizer_.emplace(oo);
		layout_opts_.ring_field = L.ring_field;
		layout_opts_.time_field = L.time_field;
		layout_opts_.intensity_field = L.intensity_field;
		layout_opts_.time_encoding = L.time_encoding;
	}
	if (lidar_kind_ == MsgKind::VelodyneScan && !L.calibration_file.empty())
	{
		try
		{
			velodyne_calib_ = loadVelodyneCalibration(L.calibration_file);
		}
		catch (const std::exception& e)
		{
			throw ConversionSetupError(std::string("[") + kLidar +
			                           "] calibration_file: " + e.what());
		}
	}
}

void Converter::readTfStatic()
{
	if (!opts_.use_tf_static) return;
	const TopicInfo* t = bag_->findTopic(opts_.tf_static_topic);
	if (!t) return;
	if (t->kind != MsgKind::TfMessage)
		throw ConversionSetupError("topic " + opts_.tf_static_topic +
		                           " has type " + t->type +
		                           ", expected tf2_msgs/TFMessage");
	TopicReport r;
	r.role = "tf_static";
	r.topic = t->name;
	r.type = t->type;
	// A separate pass over this one small topic, so the extrinsics are known
	// before the first sensor message whatever the recording order.
	auto reader = BagReader::open(bag_path_);
	reader->select({t->name});
	BagMessage m;
	for (;;)
	{
		try
		{
			if (!reader->next(m)) break;
		}
		catch (const BagError& e)
		{
			// A damaged bag: keep the transforms read so far; the main pass
			// reports the damage.
			FS_LOG_WARN("reading " << t->name << ": " << e.what());
			break;
		}
		r.messages_in++;
		try
		{
			tf_.add(decodeTfMessage(m.data, m.size, m.wire));
		}
		catch (const DecodeError& e)
		{
			throw ConversionSetupError("topic " + t->name + " message #" +
			                           std::to_string(m.index) + ": " +
			                           e.what());
		}
	}
	tf_in_bag_ = !tf_.empty();
	r.detail = tf_.describe();
	report_.topics.push_back(r);
}

const mrpt::poses::CPose3D& Converter::poseOf(Sensor& s,
                                              const std::string& header_frame)
{
	const std::string frame = canonicalFrame(
	    s.opts->frame_id.empty() ? header_frame : s.opts->frame_id);
	if (s.pose_resolved)
	{
		if (frame != s.frame)
			core::logOnce(core::LogLevel::Warn, "frame-change-" + s.opts->topic,
			              "topic " + s.opts->topic +
			                  " changes frame_id from '" + s.frame + "' to '" +
			                  frame + "'; keeping the first frame's pose");
		return s.pose;
	}
	s.frame = frame;
	s.pose_resolved = true;
	if (tf_in_bag_ && tf_.lookup(frame, opts_.base_frame, s.pose))
	{
		rep(s).pose_source = opts_.tf_static_topic + " (" + frame + " -> " +
		                     canonicalFrame(opts_.base_frame) + ") " +
		                     poseText(s.pose);
		return s.pose;
	}
	s.pose = iniPose(*s.opts);
	rep(s).pose_source =
	    std::string("INI [") + s.section + "] pose_* " + poseText(s.pose) +
	    (tf_in_bag_
	         ? " (frame '" + frame + "' has no chain to '" + opts_.base_frame +
	               "' in " + opts_.tf_static_topic + ")"
	         : " (no " + opts_.tf_static_topic + " in the bag)");
	if (tf_in_bag_)
		FS_LOG_WARN("topic " << s.opts->topic << ": frame '" << frame
		                     << "' not found under '" << opts_.base_frame
		                     << "' in " << opts_.tf_static_topic << " (has: "
		                     << tf_.describe() << "); using the INI pose");
	return s.pose;
}

void Converter::handleCloud(const BagMessage& m, Sensor& s, io::RawlogWriter& w)
{
	auto& r = rep(s);
	const PointCloud2Msg cloud = decodePointCloud2(m.data, m.size, m.wire);
	const CloudLayout layout = analyzeCloudLayout(cloud, layout_opts_);
	if (!layout_logged_)
	{
		r.detail = "layout: " + layout.describe();
		FS_LOG_INFO("topic " << s.opts->topic << ": PointCloud2 "
		                     << layout.describe());
		layout_logged_ = true;
	}
	const std::string& mode = opts_.lidar.cloud_output;
	const bool rotating = mode == "CObservationRotatingScan" ||
	                      (mode == "auto" && layout.ring.present);
	if (rotating && !layout.ring.present)
		throw DecodeError(
		    "the cloud has no ring field, which CObservationRotatingScan "
		    "needs (set ring_field, or cloud_output = CObservationPointCloud)");
	pts_invalid_ += extractCloudPoints(cloud, layout, cloud_pts_);
	if (cloud_pts_.empty())
	{
		r.skipped["no valid point"]++;
		return;
	}
	const auto& pose = poseOf(s, cloud.header.frame_id);
	const auto received = fromUnixNs(m.time_ns);
	if (rotating)
	{
		mrpt::obs::CObservationRotatingScan obs;
		OrganizeStats st;
		organizer_->organize(cloud_pts_, cloud.header.stamp_ns,
		                     layout.time.present, obs, &st);
		obs.sensorLabel = s.opts->sensor_label;
		obs.sensorPose = pose;
		obs.originalReceivedTimestamp = received;
		pts_in_ += st.points_in;
		pts_out_ += st.points_out;
		pts_range_ += st.out_of_range;
		pts_dup_ += st.collisions;
		w.write(obs);
	}
	else
	{
		auto obs = mrpt::obs::CObservationPointCloud::Create();
		obs->sensorLabel = s.opts->sensor_label;
		obs->sensorPose = pose;
		double t_min = 0;
		if (layout.time.present)
		{
			t_min = cloud_pts_[0].t_s;
			for (const auto& p : cloud_pts_) t_min = std::min(t_min, p.t_s);
			// MRPT 2.5.8 has no per-point time channel: the time after the
			// observation timestamp rides in the G channel of a coloured
			// map, intensity in R (see doc/ingest.md).
			auto map = mrpt::maps::CColouredPointsMap::Create();
			map->reserve(cloud_pts_.size());
			for (const auto& p : cloud_pts_)
				map->insertPointRGB(p.x, p.y, p.z, p.intensity,
				                    static_cast<float>(p.t_s - t_min), 0.f);
			obs->pointcloud = map;
		}
		else
		{
			auto map = mrpt::maps::CPointsMapXYZI::Create();
			map->reserve(cloud_pts_.size());
			for (const auto& p : cloud_pts_)
				map->insertPointRGB(p.x, p.y, p.z, p.intensity, 0, 0);
			obs->pointcloud = map;
		}
		obs->timestamp =
		    fromUnixNs(cloud.header.stamp_ns + std::llround(t_min * 1e9));
		pts_in_ += cloud_pts_.size();
		pts_out_ += cloud_pts_.size();
		w.write(*obs);
	}
	r.observations_out++;
}

void Converter::handleVelodyne(const BagMessage& m, Sensor& s,
                               io::RawlogWriter& w)
{
	auto& r = rep(s);
	const VelodyneScanMsg msg = decodeVelodyneScan(m.data, m.size, m.wire);
	if (msg.packets.empty())
	{
		r.skipped["no packets"]++;
		return;
	}
	const auto& L = opts_.lidar;
	const uint8_t byte = msg.packets[0].data[1205];
	// Early firmware leaves the model byte 0: then the configured model (or
	// its calibration) says how to decode.
	size_t lasers = velodyne_calib_ ? velodyne_calib_->lasers.size() : 0;
	if (!lasers && L.lidar_model != "auto")
		lasers = core::lidarModelByName(L.lidar_model).rings();
	const std::string model =
	    lidarModelForVelodyneId(resolveVelodyneModel(byte, lasers));
	if (model.empty())
		throw DecodeError(
		    "velodyne packets have model byte " + std::to_string(byte) +
		    ", not a supported VLP-16 / HDL-32E / VLP-32C (name the model "
		    "in lidar_model)");
	if (L.lidar_model != "auto" &&
	    core::findLidarModel(L.lidar_model) != core::findLidarModel(model))
		throw DecodeError("the packets come from a " + model + " but [" +
		                  std::string(kLidar) +
		                  "] lidar_model = " + L.lidar_model);
	if (!velodyne_calib_)
	{
		velodyne_calib_ = defaultVelodyneCalibration(model);
		FS_LOG_INFO("topic "
		            << s.opts->topic << ": " << model
		            << " packets, calibration: " << velodyne_calib_->source);
	}
	if (r.detail.empty())
		r.detail = model + " packets, calibration " + velodyne_calib_->source;
	mrpt::obs::CObservationVelodyneScan vel;
	velodyneScanFromMsg(msg, *velodyne_calib_, vel);
	vel.sensorLabel = s.opts->sensor_label;
	vel.sensorPose = poseOf(s, msg.header.frame_id);
	vel.originalReceivedTimestamp = fromUnixNs(m.time_ns);
	if (L.velodyne_output == "CObservationVelodyneScan")
	{
		w.write(vel);
	}
	else
	{
		VelodyneDecodeOptions d;
		const auto& lm = core::lidarModelByName(model);
		d.min_range_m = L.min_range_m > 0 ? L.min_range_m : lm.min_range_m;
		d.max_range_m = L.max_range_m > 0 ? L.max_range_m : lm.max_range_m;
		d.dual = parseDualReturn(L.dual_return);
		mrpt::obs::CObservationRotatingScan rs;
		OrganizeStats st;
		velodyneToRotatingScan(vel, rs, d, &st);
		pts_in_ += st.points_in;
		pts_out_ += st.points_out;
		pts_range_ += st.out_of_range;
		pts_dup_ += st.collisions;
		w.write(rs);
	}
	r.observations_out++;
}

void Converter::handle(const BagMessage& m, Sensor& s, io::RawlogWriter& w)
{
	auto& r = rep(s);
	r.messages_in++;
	switch (m.topic->kind)
	{
		case MsgKind::PointCloud2:
			handleCloud(m, s, w);
			break;
		case MsgKind::VelodyneScan:
			handleVelodyne(m, s, w);
			break;
		case MsgKind::Imu:
		{
			const ImuMsg msg = decodeImu(m.data, m.size, m.wire);
			mrpt::obs::CObservationIMU obs;
			imuFromMsg(msg, obs);
			obs.sensorLabel = s.opts->sensor_label;
			obs.sensorPose = poseOf(s, msg.header.frame_id);
			w.write(obs);
			r.observations_out++;
			break;
		}
		case MsgKind::NavSatFix:
		{
			const NavSatFixMsg msg = decodeNavSatFix(m.data, m.size, m.wire);
			mrpt::obs::CObservationGPS obs;
			gpsFromMsg(msg, obs);
			obs.sensorLabel = s.opts->sensor_label;
			obs.sensorPose = poseOf(s, msg.header.frame_id);
			obs.originalReceivedTimestamp = fromUnixNs(m.time_ns);
			w.write(obs);
			r.observations_out++;
			break;
		}
		default:
			throw DecodeError("unsupported message type " + m.topic->type);
	}
}

void Converter::finishDetail()
{
	for (auto& [topic, s] : sensors_)
	{
		auto& r = rep(s);
		if (r.role != "lidar" || pts_in_ + pts_invalid_ == 0) continue;
		std::ostringstream os;
		os << "points: " << pts_in_ << " valid";
		if (pts_invalid_) os << ", " << pts_invalid_ << " NaN/zero dropped";
		os << ", " << pts_out_ << " written";
		if (pts_range_) os << ", " << pts_range_ << " out of range";
		if (pts_dup_)
			os << ", " << pts_dup_ << " second returns in an occupied cell";
		if (organizer_ && lidar_kind_ == MsgKind::PointCloud2)
			os << "; ring order " << ringOrderName(organizer_->ringOrder())
			   << " for " << organizer_->model().name;
		r.detail += (r.detail.empty() ? "" : "\n") + os.str();
	}
}

ConversionReport Converter::run(const std::string& out_path, bool show_progress)
{
	try
	{
		bag_ = BagReader::open(bag_path_);
	}
	catch (const BagError& e)
	{
		throw ConversionSetupError(e.what());
	}
	validate();
	readTfStatic();
	if (!bag_->damage().empty())
		FS_LOG_WARN("bag '" << bag_path_ << "': " << bag_->damage()
		                    << "; converting the messages before the damage");

	std::vector<std::string> topics;
	for (const auto& [t, s] : sensors_) topics.push_back(t);
	bag_->select(topics);

	io::RawlogWriter writer(out_path, opts_.compress_level);
	core::ProgressReporter progress;
	BagMessage m;
	int64_t first_ns = -1;
	uint64_t scans = 0;
	try
	{
		while (bag_->next(m))
		{
			Sensor& s = sensors_.at(m.topic->name);
			try
			{
				handle(m, s, writer);
			}
			catch (const std::exception& e)
			{
				throw BagError("topic " + m.topic->name + " message #" +
				                   std::to_string(m.index) + " (" +
				                   m.topic->type + "): " + e.what(),
				               m.topic->name, static_cast<int64_t>(m.index));
			}
			if (first_ns < 0) first_ns = m.time_ns;
			if (s.opts == &opts_.lidar) scans = rep(s).observations_out;
			if (show_progress)
				progress.update(scans, bag_->fractionRead(),
				                (m.time_ns - first_ns) * 1e-9);
		}
	}
	catch (const std::exception& e)
	{
		report_.error = e.what();
	}
	if (show_progress) progress.finish();
	report_.observations_written = writer.count();
	writer.close();
	finishDetail();
	return report_;
}
}  // namespace

// ------------------------------------------------------------------ options
void SensorTopicOptions::loadFromConfigFile(
    const mrpt::config::CConfigFileBase& c, const std::string& s)
{
	FS_LOAD(c, s, topic);
	FS_LOAD(c, s, sensor_label);
	FS_LOAD(c, s, frame_id);
	FS_LOAD(c, s, pose_x_m);
	FS_LOAD(c, s, pose_y_m);
	FS_LOAD(c, s, pose_z_m);
	FS_LOAD(c, s, pose_yaw_deg);
	FS_LOAD(c, s, pose_pitch_deg);
	FS_LOAD(c, s, pose_roll_deg);
	if (!topic.empty() && sensor_label.empty())
		throw core::ConfigError(core::configOrigin(c) + ": [" + s +
		                        "] sensor_label must not be empty");
}

void SensorTopicOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                          const std::string& s) const
{
	c.write(s, "topic", topic);
	c.write(s, "sensor_label", sensor_label);
	c.write(s, "frame_id", frame_id);
	c.write(s, "pose_x_m", pose_x_m);
	c.write(s, "pose_y_m", pose_y_m);
	c.write(s, "pose_z_m", pose_z_m);
	c.write(s, "pose_yaw_deg", pose_yaw_deg);
	c.write(s, "pose_pitch_deg", pose_pitch_deg);
	c.write(s, "pose_roll_deg", pose_roll_deg);
}

void LidarTopicOptions::loadFromConfigFile(
    const mrpt::config::CConfigFileBase& c, const std::string& s)
{
	SensorTopicOptions::loadFromConfigFile(c, s);
	FS_LOAD(c, s, lidar_model);
	FS_LOAD(c, s, cloud_output);
	FS_LOAD(c, s, ring_field);
	FS_LOAD(c, s, time_field);
	FS_LOAD(c, s, intensity_field);
	FS_LOAD(c, s, time_encoding);
	FS_LOAD(c, s, ring_order);
	FS_LOAD(c, s, range_resolution_m);
	FS_LOAD(c, s, rate_hz);
	FS_LOAD(c, s, rotation);
	FS_LOAD(c, s, min_range_m);
	FS_LOAD(c, s, max_range_m);
	FS_LOAD(c, s, calibration_file);
	FS_LOAD(c, s, velodyne_output);
	FS_LOAD(c, s, dual_return);
	if (lidar_model != "auto" && !core::findLidarModel(lidar_model))
	{
		std::string known;
		for (const auto& n : core::knownLidarModels())
			known += (known.empty() ? "" : ", ") + n;
		throw core::ConfigError(core::configOrigin(c) + ": [" + s +
		                        "] lidar_model = '" + lidar_model +
		                        "' is unknown (known: " + known + ", auto)");
	}
	requireOneOf(
	    c, s, "cloud_output", cloud_output,
	    {"auto", "CObservationRotatingScan", "CObservationPointCloud"});
	requireOneOf(c, s, "time_encoding", time_encoding,
	             {"auto", "none", "relative_s", "relative_ns", "absolute_s",
	              "absolute_ns"});
	requireOneOf(
	    c, s, "ring_order", ring_order,
	    {"auto", "native", "elevation_ascending", "elevation_descending"});
	requireOneOf(c, s, "rotation", rotation, {"auto", "cw", "ccw"});
	requireOneOf(c, s, "velodyne_output", velodyne_output,
	             {"CObservationVelodyneScan", "CObservationRotatingScan"});
	requireOneOf(c, s, "dual_return", dual_return,
	             {"strongest", "last", "both"});
	auto positive = [&](const char* k, double v)
	{
		if (!(v > 0))
			throw core::ConfigError(core::configOrigin(c) + ": [" + s + "] " +
			                        k + " must be > 0");
	};
	positive("range_resolution_m", range_resolution_m);
	positive("rate_hz", rate_hz);
}

void LidarTopicOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                         const std::string& s) const
{
	SensorTopicOptions::saveToConfigFile(c, s);
	c.write(s, "lidar_model", lidar_model);
	c.write(s, "cloud_output", cloud_output);
	c.write(s, "ring_field", ring_field);
	c.write(s, "time_field", time_field);
	c.write(s, "intensity_field", intensity_field);
	c.write(s, "time_encoding", time_encoding);
	c.write(s, "ring_order", ring_order);
	c.write(s, "range_resolution_m", range_resolution_m);
	c.write(s, "rate_hz", rate_hz);
	c.write(s, "rotation", rotation);
	c.write(s, "min_range_m", min_range_m);
	c.write(s, "max_range_m", max_range_m);
	c.write(s, "calibration_file", calibration_file);
	c.write(s, "velodyne_output", velodyne_output);
	c.write(s, "dual_return", dual_return);
}

Bag2RawlogOptions::Bag2RawlogOptions()
{
	lidar.topic = "/velodyne_points";
	lidar.sensor_label = "lidar";
	imu.topic = "/imu/data";
	imu.sensor_label = "imu";
	gnss.topic = "/gps/fix";
	gnss.sensor_label = "gnss";
}

void Bag2RawlogOptions::loadFromConfigFile(
    const mrpt::config::CConfigFileBase& c, const std::string&)
{
	FS_LOAD(c, kMain, base_frame);
	FS_LOAD(c, kMain, use_tf_static);
	FS_LOAD(c, kMain, tf_static_topic);
	FS_LOAD(c, kMain, compress_level);
	if (compress_level < 0 || compress_level > 9)
		throw core::ConfigError(core::configOrigin(c) + ": [" + kMain +
		                        "] compress_level must be 0..9");
	lidar.loadFromConfigFile(c, kLidar);
	imu.loadFromConfigFile(c, kImu);
	gnss.loadFromConfigFile(c, kGnss);
}

void Bag2RawlogOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                         const std::string&) const
{
	c.write(kMain, "base_frame", base_frame);
	c.write(kMain, "use_tf_static", use_tf_static);
	c.write(kMain, "tf_static_topic", tf_static_topic);
	c.write(kMain, "compress_level", compress_level);
	lidar.saveToConfigFile(c, kLidar);
	imu.saveToConfigFile(c, kImu);
	gnss.saveToConfigFile(c, kGnss);
}

ConversionReport convertBag(const std::string& bag_path,
                            const std::string& rawlog_path,
                            const Bag2RawlogOptions& opts, bool show_progress)
{
	Converter c(opts, bag_path);
	return c.run(rawlog_path, show_progress);
}

void printTopicList(const BagReader& bag, std::ostream& os)
{
	os << "bag: " << bag.path() << " ("
	   << (bag.format() == BagFormat::Ros1 ? "ROS 1" : "ROS 2") << ")\n";
	if (!bag.damage().empty()) os << "damaged: " << bag.damage() << "\n";
	size_t w_topic = 5, w_type = 4;
	for (const auto& t : bag.topics())
	{
		w_topic = std::max(w_topic, t.name.size());
		w_type = std::max(w_type, t.type.size());
	}
	os << std::left << std::setw(w_topic + 2) << "topic"
	   << std::setw(w_type + 2) << "type" << std::right << std::setw(10)
	   << "messages" << std::setw(10) << "rate_Hz" << std::setw(10) << "span_s"
	   << "  converts as\n";
	for (const auto& t : bag.topics())
	{
		const char* role = t.kind == MsgKind::PointCloud2    ? "lidar"
		                   : t.kind == MsgKind::VelodyneScan ? "lidar (packets)"
		                   : t.kind == MsgKind::Imu          ? "imu"
		                   : t.kind == MsgKind::NavSatFix    ? "gnss"
		                   : t.kind == MsgKind::TfMessage    ? "extrinsics"
		                                                     : "-";
		os << std::left << std::setw(w_topic + 2) << t.name
		   << std::setw(w_type + 2) << t.type << std::right << std::setw(10)
		   << t.count << std::setw(10) << std::fixed << std::setprecision(2)
		   << t.rateHz() << std::setw(10) << std::setprecision(2)
		   << (t.count > 1 ? (t.last_ns - t.first_ns) * 1e-9 : 0.0) << "  "
		   << role << "\n";
	}
}

void printReport(const ConversionReport& r, std::ostream& os)
{
	os << "summary:\n";
	for (const auto& t : r.topics)
	{
		os << "  " << t.role << ": " << t.topic << " (" << t.type << ")";
		if (!t.label.empty()) os << " -> label '" << t.label << "'";
		os << "\n    messages in: " << t.messages_in;
		if (t.role != "tf_static")
			os << ", observations out: " << t.observations_out;
		for (const auto& [why, n] : t.skipped)
			os << ", skipped (" << why << "): " << n;
		os << "\n";
		if (!t.pose_source.empty())
			os << "    sensorPose from " << t.pose_source << "\n";
		if (!t.detail.empty())
		{
			std::istringstream is(t.detail);
			std::string line;
			while (std::getline(is, line)) os << "    " << line << "\n";
		}
	}
	os << "  observations written: " << r.observations_written << "\n";
	if (!r.ok()) os << "  STOPPED: " << r.error << "\n";
}

}  // namespace forest_slam::ingest
