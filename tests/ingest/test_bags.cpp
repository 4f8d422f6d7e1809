// bag2rawlog's engine on bags written here: ROS 1 through librosbag-storage
// (as the ROS drivers record them), ROS 2 as rosbag2's sqlite3 schema with
// CDR payloads, plus the real nebula ROS 2 bags. Checks counts, labels,
// extrinsics (/tf_static vs INI), exact points, and damaged bags.
#include <forest_slam/core/config.h>
#include <forest_slam/core/scan_points.h>
#include <forest_slam/ingest/bag_converter.h>
#include <forest_slam/ingest/observations.h>
#include <forest_slam/io/rawlog_reader.h>

#include <gtest/gtest.h>
#include <mrpt/obs/CObservationGPS.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/obs/CObservationVelodyneScan.h>
#include <mrpt/obs/gnss_messages_ascii_nmea.h>
#include <mrpt/obs/gnss_messages_novatel.h>
#include <rosbag/bag.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>
#include <sqlite3.h>
#include <tf2_msgs/TFMessage.h>

#include <filesystem>
#include <map>

#include "bag_fixtures.h"
#include "test_helpers.h"

using namespace forest_slam;
using namespace forest_slam::ingest;
using ingest_test::CdrWriter;
using ingest_test::sharedData;
using ingest_test::TempDir;
using namespace ingest_test;

// A pre-serialized message, to record velodyne_msgs/VelodyneScan (no Debian
// headers) with librosbag-storage.
struct RawVelodyneScan
{
	std::vector<uint8_t> bytes;
};
namespace ros::message_traits
{
template <>
struct MD5Sum<RawVelodyneScan>
{
	static const char* value() { return "50804fc9533a0e579e6322c04ae70566"; }
	static const char* value(const RawVelodyneScan&) { return value(); }
};
template <>
struct DataType<RawVelodyneScan>
{
	static const char* value() { return "velodyne_msgs/VelodyneScan"; }
	static const char* value(const RawVelodyneScan&) { return value(); }
};
template <>
struct Definition<RawVelodyneScan>
{
	static const char* value()
	{
		return "Header header\nVelodynePacket[] packets\n";
	}
	static const char* value(const RawVelodyneScan&) { return value(); }
};
}  // namespace ros::message_traits
namespace ros::serialization
{
template <>
struct Serializer<RawVelodyneScan>
{
	template <typename Stream>
	static void write(Stream& s, const RawVelodyneScan& m)
	{
		std::memcpy(s.advance(static_cast<uint32_t>(m.bytes.size())),
		            m.bytes.data(), m.bytes.size());
	}
	template <typename Stream>
	static void read(Stream&, RawVelodyneScan&)
	{
	}
	static uint32_t serializedLength(const RawVelodyneScan& m)
	{
		return static_cast<uint32_t>(m.bytes.size());
	}
};
}  // namespace ros::serialization

namespace
{
struct RawlogContents
{
	std::vector<std::shared_ptr<mrpt::obs::CObservationRotatingScan>> scans;
	std::vector<std::shared_ptr<mrpt::obs::CObservationIMU>> imu;
	std::vector<std::shared_ptr<mrpt::obs::CObservationGPS>> gps;
	std::vector<mrpt::obs::CObservation::Ptr> other;
};

RawlogContents readRawlog(const std::string& path)
{
	RawlogContents c;
	io::RawlogReader r(path);
	while (auto o = r.next())
	{
		if (auto s =
		        std::dynamic_pointer_cast<mrpt::obs::CObservationRotatingScan>(
		            o))
			c.scans.push_back(s);
		else if (auto i =
		             std::dynamic_pointer_cast<mrpt::obs::CObservationIMU>(o))
			c.imu.push_back(i);
		else if (auto g =
		             std::dynamic_pointer_cast<mrpt::obs::CObservationGPS>(o))
			c.gps.push_back(g);
		else
			c.other.push_back(o);
	}
	return c;
}

Bag2RawlogOptions optionsFrom(const std::string& ini_text)
{
	auto cfg = core::TrackedConfig::fromText(ini_text, "test.ini");
	Bag2RawlogOptions o;
	o.loadFromConfigFile(cfg);
	cfg.checkNoUnknownKeys();
	return o;
}

void expectPose(const mrpt::poses::CPose3D& p, double x, double y, double z,
                double yaw)
{
	EXPECT_NEAR(p.x(), x, 1e-9);
	EXPECT_NEAR(p.y(), y, 1e-9);
	EXPECT_NEAR(p.z(), z, 1e-9);
	EXPECT_NEAR(p.yaw(), yaw, 1e-9);
}

/** The checks shared by the ROS 1 and ROS 2 round trips. */
void checkConverted(const std::string& rawlog, bool tf)
{
	const auto c = readRawlog(rawlog);
	ASSERT_EQ(c.scans.size(), size_t(kScans));
	ASSERT_EQ(c.imu.size(), size_t(kScans * kImuPerScan));
	ASSERT_EQ(c.gps.size(), 2u);
	EXPECT_TRUE(c.other.empty());
	for (int k = 0; k < kScans; k++)
	{
		const auto& s = *c.scans[k];
		EXPECT_EQ(s.sensorLabel, "lidar");
		EXPECT_EQ(s.lidarModel, "VLP16");
		const auto ref = scanAt(k);
		ASSERT_EQ(s.columnCount, ref.columnCount);
		for (int r = 0; r < 16; r++)
			for (int col = 0; col < ref.columnCount; col++)
				ASSERT_EQ(s.rangeImage(r, col), ref.rangeImage(r, col))
				    << k << " " << r << " " << col;
		EXPECT_NEAR(mrpt::Clock::toDouble(s.timestamp), kT0 + 0.1 * k, 1e-6);
		const auto a = core::unpackRotatingScan(s),
		           b = core::unpackRotatingScan(ref);
		ASSERT_EQ(a.points.size(), b.points.size());
		for (size_t i = 0; i < a.points.size(); i += 97)
		{
			EXPECT_NEAR(a.points[i].x, b.points[i].x, 2e-5);
			EXPECT_NEAR(a.points[i].y, b.points[i].y, 2e-5);
			EXPECT_NEAR(a.points[i].t_s, b.points[i].t_s, 1e-6);
		}
		if (tf)  // base_link -> mount (0.2, 0, 1) -> velodyne (0.1, 0, 0.3, yaw
		         // 90)
			expectPose(s.sensorPose, 0.3, 0, 1.3, M_PI / 2);
		else
			expectPose(s.sensorPose, 0.5, 0.25, 1.75, -M_PI / 4);
	}
	EXPECT_EQ(c.imu[3]->sensorLabel, "imu");
	EXPECT_NEAR(c.imu[3]->get(mrpt::obs::IMU_WZ), 0.003, 1e-12);
	EXPECT_NEAR(c.imu[3]->get(mrpt::obs::IMU_Z_ACC), 9.81, 1e-12);
	EXPECT_FALSE(c.imu[3]->has(mrpt::obs::IMU_ORI_QUAT_W))
	    << "orientation marked absent";
	if (tf) expectPose(c.imu[0]->sensorPose, -0.05, 0, 0.1, 0);
	const auto& g = *c.gps[1];
	EXPECT_EQ(g.sensorLabel, "gnss");
	const auto& gga = g.getMsgByClass<mrpt::obs::gnss::Message_NMEA_GGA>();
	EXPECT_EQ(gga.fields.fix_quality, 4);
	EXPECT_EQ(gpsStatusFromGga(gga.fields.fix_quality), 2);
	EXPECT_NEAR(gga.fields.latitude_degrees, 59.66001, 1e-9);
	EXPECT_EQ(c.gps[0]
	              ->getMsgByClass<mrpt::obs::gnss::Message_NMEA_GGA>()
	              .fields.fix_quality,
	          1);
	std::array<double, 9> cov{};
	ASSERT_TRUE(navSatCovariance(g, cov));
	EXPECT_FLOAT_EQ(cov[1], 0.001f);
	EXPECT_FLOAT_EQ(cov[4], 0.05f);
	EXPECT_FLOAT_EQ(cov[8], 0.2f);
	const auto& best =
	    g.getMsgByClass<mrpt::obs::gnss::Message_NV_OEM6_BESTPOS>();
	EXPECT_FLOAT_EQ(best.fields.lat_sigma, std::sqrt(0.05f));
	EXPECT_FLOAT_EQ(best.fields.hgt_sigma, std::sqrt(0.2f));
	EXPECT_EQ(best.fields.position_type,
	          mrpt::obs::gnss::nv_oem6_position_type::NARROW_INT);
	if (tf) expectPose(g.sensorPose, 0, 0, 1.5, 0);
}

const char* kIniPoses = R"(
[bag2rawlog_lidar]
pose_x_m = 0.5
pose_y_m = 0.25
pose_z_m = 1.75
pose_yaw_deg = -45
)";

// ------------------------------------------------------------- ROS 2 writer
struct Ros2Writer
{
	sqlite3* db = nullptr;
	std::map<std::string, int> ids;
	explicit Ros2Writer(const std::string& file)
	{
		EXPECT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
		exec("BEGIN");
		exec(
		    "CREATE TABLE schema(schema_version INTEGER PRIMARY KEY,ros_distro "
		    "TEXT NOT NULL);"
		    "CREATE TABLE metadata(id INTEGER PRIMARY KEY,metadata_version "
		    "INTEGER NOT NULL,"
		    "metadata TEXT NOT NULL);"
		    "CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT "
		    "NULL,type TEXT NOT NULL,"
		    "serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT "
		    "NULL);"
		    "CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT "
		    "NULL,"
		    "timestamp INTEGER NOT NULL, data BLOB NOT NULL);"
		    "CREATE INDEX timestamp_idx ON messages (timestamp ASC);");
	}
	~Ros2Writer()
	{
		exec("COMMIT");
		sqlite3_close(db);
	}
	void exec(const std::string& sql)
	{
		char* err = nullptr;
		EXPECT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err),
		          SQLITE_OK)
		    << (err ? err : "");
		sqlite3_free(err);
	}
	void topic(const std::string& name, const std::string& type)
	{
		const int id = static_cast<int>(ids.size()) + 1;
		ids[name] = id;
		exec("INSERT INTO topics VALUES(" + std::to_string(id) + ",'" + name +
		     "','" + type + "','cdr','')");
	}
	void write(const std::string& name, double t,
	           const std::vector<uint8_t>& data)
	{
		sqlite3_stmt* st;
		sqlite3_prepare_v2(
		    db, "INSERT INTO messages(topic_id,timestamp,data) VALUES(?,?,?)",
		    -1, &st, nullptr);
		sqlite3_bind_int(st, 1, ids.at(name));
		sqlite3_bind_int64(st, 2,
		                   static_cast<sqlite3_int64>(std::llround(t * 1e9)));
		sqlite3_bind_blob(st, 3, data.data(), static_cast<int>(data.size()),
		                  SQLITE_TRANSIENT);
		EXPECT_EQ(sqlite3_step(st), SQLITE_DONE);
		sqlite3_finalize(st);
	}
};

void cdrHeader(CdrWriter& w, const std_msgs::Header& h)
{
	w.header(static_cast<int32_t>(h.stamp.sec), h.stamp.nsec, h.frame_id);
}

std::vector<uint8_t> cdr(const sensor_msgs::PointCloud2& m)
{
	CdrWriter w;
	cdrHeader(w, m.header);
	w.put<uint32_t>(m.height);
	w.put<uint32_t>(m.width);
	w.put<uint32_t>(static_cast<uint32_t>(m.fields.size()));
	for (const auto& f : m.fields)
	{
		w.str(f.name);
		w.put<uint32_t>(f.offset);
		w.put<uint8_t>(f.datatype);
		w.put<uint32_t>(f.count);
	}
	w.put<uint8_t>(m.is_bigendian);
	w.put<uint32_t>(m.point_step);
	w.put<uint32_t>(m.row_step);
	w.put<uint32_t>(static_cast<uint32_t>(m.data.size()));
	w.bytes(m.data.data(), m.data.size());
	w.put<uint8_t>(m.is_dense);
	return w.data();
}

std::vector<uint8_t> cdr(const sensor_msgs::Imu& m)
{
	CdrWriter w;
	cdrHeader(w, m.header);
	for (double v :
	     {m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w})
		w.put<double>(v);
	for (double v : m.orientation_covariance) w.put<double>(v);
	for (double v :
	     {m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z})
		w.put<double>(v);
	for (double v : m.angular_velocity_covariance) w.put<double>(v);
	for (double v : {m.linear_acceleration.x, m.linear_acceleration.y,
	                 m.linear_acceleration.z})
		w.put<double>(v);
	for (double v : m.linear_acceleration_covariance) w.put<double>(v);
	return w.data();
}

std::vector<uint8_t> cdr(const sensor_msgs::NavSatFix& m)
{
	CdrWriter w;
	cdrHeader(w, m.header);
	w.put<int8_t>(m.status.status);
	w.put<uint16_t>(m.status.service);
	w.put<double>(m.latitude);
	w.put<double>(m.longitude);
	w.put<double>(m.altitude);
	for (double v : m.position_covariance) w.put<double>(v);
	w.put<uint8_t>(m.position_covariance_type);
	return w.data();
}

std::vector<uint8_t> cdr(const tf2_msgs::TFMessage& m)
{
	CdrWriter w;
	w.put<uint32_t>(static_cast<uint32_t>(m.transforms.size()));
	for (const auto& t : m.transforms)
	{
		cdrHeader(w, t.header);
		w.str(t.child_frame_id);
		for (double v : {t.transform.translation.x, t.transform.translation.y,
		                 t.transform.translation.z, t.transform.rotation.x,
		                 t.transform.rotation.y, t.transform.rotation.z,
		                 t.transform.rotation.w})
			w.put<double>(v);
	}
	return w.data();
}
}  // namespace

TEST(IngestBags, Ros1RoundTripWithTfStatic)
{
	TempDir tmp("ros1tf");
	writeRos1Bag(tmp / "run.bag", {});
	const auto rep = convertBag(tmp / "run.bag", tmp / "run.rawlog",
	                            optionsFrom(kIniPoses), false);
	ASSERT_TRUE(rep.ok()) << rep.error;
	EXPECT_EQ(rep.observations_written,
	          size_t(kScans + kScans * kImuPerScan + 2));
	checkConverted(tmp / "run.rawlog", true);
	bool saw_tf_pose = false;
	for (const auto& t : rep.topics)
		if (t.role == "lidar")
		{
			saw_tf_pose = t.pose_source.find("/tf_static") == 0;
			EXPECT_NE(t.detail.find("elevation_ascending"), std::string::npos)
			    << t.detail;
		}
	EXPECT_TRUE(saw_tf_pose);
	std::ostringstream os;
	printReport(rep, os);
	EXPECT_NE(os.str().find("observations out: 5"), std::string::npos)
	    << os.str();
}

TEST(IngestBags, Ros1WithoutTfStaticUsesIniPoses)
{
	TempDir tmp("ros1ini");
	BagSpec spec;
	spec.tf = false;
	spec.lz4 = true;
	writeRos1Bag(tmp / "run.bag", spec);
	const auto rep = convertBag(tmp / "run.bag", tmp / "run.rawlog",
	                            optionsFrom(kIniPoses), false);
	ASSERT_TRUE(rep.ok()) << rep.error;
	checkConverted(tmp / "run.rawlog", false);
}

TEST(IngestBags, ListShowsTopicsCountsRates)
{
	TempDir tmp("list");
	writeRos1Bag(tmp / "run.bag", {});
	auto bag = BagReader::open(tmp / "run.bag");
	std::ostringstream os;
	printTopicList(*bag, os);
	const std::string s = os.str();
	EXPECT_NE(s.find("/velodyne_points"), std::string::npos);
	EXPECT_NE(s.find("sensor_msgs/PointCloud2"), std::string::npos);
	const auto* imu = bag->findTopic("/imu/data");
	ASSERT_TRUE(imu);
	EXPECT_EQ(imu->count, size_t(kScans * kImuPerScan));
	EXPECT_NEAR(imu->rateHz(), 100.0, 1e-4);
	EXPECT_NE(s.find("100.00"), std::string::npos) << s;
}

TEST(IngestBags, Ros1TruncatedBagKeepsWhatCameBefore)
{
	for (bool lz4 : {false, true})
	{
		TempDir tmp(lz4 ? "trunc_lz4" : "trunc");
		BagSpec spec;
		spec.lz4 = lz4;
		spec.chunk_bytes =
		    20000;  // many chunks, so the cut leaves several whole
		writeRos1Bag(tmp / "full.bag", spec);
		const auto size = std::filesystem::file_size(tmp / "full.bag");
		std::filesystem::copy_file(tmp / "full.bag", tmp / "cut.bag");
		std::filesystem::resize_file(tmp / "cut.bag", size * 6 / 10);
		const auto rep = convertBag(tmp / "cut.bag", tmp / "cut.rawlog",
		                            optionsFrom(kIniPoses), false);
		ASSERT_FALSE(rep.ok());
		EXPECT_NE(rep.error.find("truncated"), std::string::npos) << rep.error;
		EXPECT_NE(rep.error.find("last complete message: #"), std::string::npos)
		    << rep.error;
		// The output is a valid rawlog holding the observations before the cut.
		const auto c = readRawlog(tmp / "cut.rawlog");
		EXPECT_GE(c.scans.size(), 1u);
		EXPECT_LT(c.scans.size(), size_t(kScans));
		EXPECT_EQ(rep.observations_written,
		          c.scans.size() + c.imu.size() + c.gps.size());
		for (size_t k = 0; k < c.scans.size(); k++)
			EXPECT_EQ(c.scans[k]->rangeImage,
			          scanAt(static_cast<int>(k)).rangeImage);
		auto bag = BagReader::open(tmp / "cut.bag");
		EXPECT_FALSE(bag->damage().empty());
	}
}

TEST(IngestBags, BadMessageStopsWithTopicAndIndex)
{
	TempDir tmp("badmsg");
	BagSpec spec;
	spec.bad_cloud = 2;
	writeRos1Bag(tmp / "run.bag", spec);
	const auto rep = convertBag(tmp / "run.bag", tmp / "run.rawlog",
	                            optionsFrom(kIniPoses), false);
	ASSERT_FALSE(rep.ok());
	EXPECT_NE(rep.error.find("/velodyne_points message #2"), std::string::npos)
	    << rep.error;
	EXPECT_NE(rep.error.find("x/y/z"), std::string::npos) << rep.error;
	const auto c = readRawlog(tmp / "run.rawlog");
	EXPECT_EQ(c.scans.size(), 2u);
	// IMU messages recorded up to the bad cloud's time (0.30 s) included.
	EXPECT_EQ(c.imu.size(), size_t(3 * kImuPerScan + 1));
}

TEST(IngestBags, WrongTypeOnSelectedTopicIsRefusedBeforeWriting)
{
	TempDir tmp("wrongtype");
	{
		rosbag::Bag bag(tmp / "run.bag", rosbag::bagmode::Write);
		bag.write("/velodyne_points", ros::Time(kT0), imuMsg(0));
		bag.close();
	}
	try
	{
		convertBag(tmp / "run.bag", tmp / "run.rawlog", Bag2RawlogOptions(),
		           false);
		FAIL();
	}
	catch (const ConversionSetupError& e)
	{
		const std::string w = e.what();
		EXPECT_NE(w.find("/velodyne_points"), std::string::npos) << w;
		EXPECT_NE(w.find("sensor_msgs/Imu"), std::string::npos) << w;
	}
	EXPECT_FALSE(std::filesystem::exists(tmp / "run.rawlog"));
	// A lidar topic the bag lacks is named with the topics it has.
	auto o = Bag2RawlogOptions();
	o.lidar.topic = "/points_raw";
	try
	{
		convertBag(tmp / "run.bag", tmp / "run.rawlog", o, false);
		FAIL();
	}
	catch (const ConversionSetupError& e)
	{
		EXPECT_NE(std::string(e.what()).find("/points_raw"), std::string::npos);
		EXPECT_NE(
		    std::string(e.what()).find("/velodyne_points (sensor_msgs/Imu)"),
		    std::string::npos)
		    << e.what();
	}
}

TEST(IngestBags, StrictIni)
{
	EXPECT_THROW(optionsFrom("[bag2rawlog_lidar]\nlidar_modle = VLP16\n"),
	             core::ConfigError);
	EXPECT_THROW(optionsFrom("[bag2rawlog_lidar]\nlidar_model = VLP-17\n"),
	             core::ConfigError);
	EXPECT_THROW(optionsFrom("[bag2rawlog_lidar]\nring_order = upside_down\n"),
	             core::ConfigError);
	EXPECT_THROW(optionsFrom("[bag2rawlog_imu]\npose_x_m = one\n"),
	             core::ConfigError);
	for (const char* ini : {"bag-vlp16.ini", "bag-ouster.ini", "bag-hesai.ini",
	                        "bag-vlp16-ros2.ini"})
	{
		auto cfg = core::TrackedConfig::fromFile(
		    std::string(FOREST_SLAM_SOURCE_DIR) + "/ini/" + ini);
		Bag2RawlogOptions o;
		EXPECT_NO_THROW(o.loadFromConfigFile(cfg)) << ini;
		EXPECT_NO_THROW(cfg.checkNoUnknownKeys()) << ini;
		EXPECT_EQ(o.lidar.sensor_label, "lidar") << ini;
		EXPECT_EQ(o.imu.sensor_label, "imu") << ini;
		EXPECT_EQ(o.gnss.sensor_label, "gnss") << ini;
	}
}

TEST(IngestBags, Ros2RoundTripWithTfStatic)
{
	TempDir tmp("ros2");
	const auto dir = tmp.path / "run";
	std::filesystem::create_directories(dir);
	{
		Ros2Writer w((dir / "run_0.db3").string());
		w.topic("/tf_static", "tf2_msgs/msg/TFMessage");
		w.topic("/velodyne_points", "sensor_msgs/msg/PointCloud2");
		w.topic("/imu/data", "sensor_msgs/msg/Imu");
		w.topic("/gps/fix", "sensor_msgs/msg/NavSatFix");
		tf2_msgs::TFMessage tf;
		tf.transforms.push_back(tfMsg("base_link", "mount", 0.2, 1.0, 0));
		tf.transforms.push_back(tfMsg("mount", "velodyne", 0.1, 0.3, M_PI / 2));
		tf.transforms.push_back(tfMsg("base_link", "imu_link", -0.05, 0.1, 0));
		tf.transforms.push_back(tfMsg("base_link", "gps", 0, 1.5, 0));
		w.write("/tf_static", kT0, cdr(tf));
		int imu = 0, fix = 0;
		for (int k = 0; k < kScans; k++)
		{
			for (int j = 0; j < kImuPerScan; j++, imu++)
				w.write("/imu/data", kT0 + 0.01 * imu, cdr(imuMsg(imu)));
			if (k % 2 == 1)
				w.write("/gps/fix", kT0 + 0.1 * k, cdr(fixMsg(fix++)));
			w.write("/velodyne_points", kT0 + 0.1 * (k + 1),
			        cdr(cloudMsg(scanAt(k))));
		}
	}
	std::ofstream(dir / "metadata.yaml")
	    << "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: "
	       "sqlite3\n"
	       "  relative_file_paths:\n    - run_0.db3\n  compression_format: "
	       "\"\"\n"
	       "  compression_mode: \"\"\n";
	const auto rep = convertBag(dir.string(), tmp / "run.rawlog",
	                            optionsFrom(kIniPoses), false);
	ASSERT_TRUE(rep.ok()) << rep.error;
	checkConverted(tmp / "run.rawlog", true);
	// A compressed bag is refused with the reason.
	std::ofstream(dir / "metadata.yaml")
	    << "rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n"
	       "  relative_file_paths:\n    - run_0.db3\n  compression_format: "
	       "zstd\n";
	EXPECT_THROW(
	    convertBag(dir.string(), tmp / "z.rawlog", Bag2RawlogOptions(), false),
	    ConversionSetupError);
}

TEST(IngestBags, VelodynePacketsRos1MatchRos2)
{
	// The real nebula VLP-16 packets, recorded again as a ROS 1 bag.
	TempDir tmp("velo1");
	const std::string ros2 =
	    sharedData("nebula_velodyne_ros2/vlp16/1673400471837873222");
	{
		auto in = BagReader::open(ros2);
		in->select({"/velodyne_packets"});
		rosbag::Bag out(tmp / "packets.bag", rosbag::bagmode::Write);
		BagMessage m;
		while (in->next(m))
		{
			const auto v = decodeVelodyneScan(m.data, m.size, m.wire);
			RawVelodyneScan raw;
			auto put32 = [&](uint32_t x)
			{
				for (int i = 0; i < 4; i++)
					raw.bytes.push_back(static_cast<uint8_t>(x >> (8 * i)));
			};
			put32(static_cast<uint32_t>(m.index));
			put32(static_cast<uint32_t>(v.header.stamp_ns / 1000000000));
			put32(static_cast<uint32_t>(v.header.stamp_ns % 1000000000));
			put32(static_cast<uint32_t>(v.header.frame_id.size()));
			raw.bytes.insert(raw.bytes.end(), v.header.frame_id.begin(),
			                 v.header.frame_id.end());
			put32(static_cast<uint32_t>(v.packets.size()));
			for (const auto& p : v.packets)
			{
				put32(static_cast<uint32_t>(p.stamp_ns / 1000000000));
				put32(static_cast<uint32_t>(p.stamp_ns % 1000000000));
				raw.bytes.insert(raw.bytes.end(), p.data.begin(), p.data.end());
			}
			out.write("/velodyne_packets",
			          ros::Time().fromNSec(static_cast<uint64_t>(m.time_ns)),
			          raw);
		}
		out.close();
	}
	const std::string ini =
	    "[bag2rawlog_lidar]\ntopic = /velodyne_packets\n"
	    "velodyne_output = CObservationRotatingScan\n"
	    "[bag2rawlog_imu]\ntopic =\n[bag2rawlog_gnss]\ntopic =\n";
	const auto r1 = convertBag(tmp / "packets.bag", tmp / "a.rawlog",
	                           optionsFrom(ini), false);
	const auto r2 = convertBag(ros2, tmp / "b.rawlog", optionsFrom(ini), false);
	ASSERT_TRUE(r1.ok() && r2.ok()) << r1.error << r2.error;
	const auto a = readRawlog(tmp / "a.rawlog"),
	           b = readRawlog(tmp / "b.rawlog");
	ASSERT_EQ(a.scans.size(), 4u);
	ASSERT_EQ(b.scans.size(), 4u);
	for (size_t i = 0; i < 4; i++)
	{
		EXPECT_EQ(a.scans[i]->rangeImage, b.scans[i]->rangeImage);
		EXPECT_EQ(a.scans[i]->timestamp, b.scans[i]->timestamp);
		EXPECT_EQ(a.scans[i]->lidarModel, "VLP16");
		EXPECT_GT(core::unpackRotatingScan(*a.scans[i]).points.size(), 14000u);
	}
}

TEST(IngestBags, NebulaBagsToRawlog)
{
	TempDir tmp("nebula");
	// Default velodyne output: the raw packets with their calibration.
	const std::string v16 =
	    "[bag2rawlog_lidar]\ntopic = /velodyne_packets\n"
	    "[bag2rawlog_imu]\ntopic =\n[bag2rawlog_gnss]\ntopic =\n";
	auto rep =
	    convertBag(sharedData("nebula_velodyne_ros2/vlp16/1673400471837873222"),
	               tmp / "v16.rawlog", optionsFrom(v16), false);
	ASSERT_TRUE(rep.ok()) << rep.error;
	io::RawlogReader r(tmp / "v16.rawlog");
	size_t n = 0;
	while (auto o = r.next())
	{
		auto v =
		    std::dynamic_pointer_cast<mrpt::obs::CObservationVelodyneScan>(o);
		ASSERT_TRUE(v);
		EXPECT_EQ(v->sensorLabel, "lidar");
		EXPECT_GE(v->scan_packets.size(), 150u);
		EXPECT_EQ(v->calibration.laser_corrections.size(), 16u);
		n++;
	}
	EXPECT_EQ(n, 4u);
	// VLP-32C: calibration from the driver's YAML, decoded to RotatingScan.
	const std::string v32 =
	    "[bag2rawlog_lidar]\ntopic = /sensing/lidar/front/velodyne_packets\n"
	    "lidar_model = auto\nvelodyne_output = CObservationRotatingScan\n"
	    "calibration_file = " +
	    sharedData("nebula_velodyne_ros2/VLP32.calib.yaml") +
	    "\n[bag2rawlog_imu]\ntopic =\n[bag2rawlog_gnss]\ntopic =\n";
	rep =
	    convertBag(sharedData("nebula_velodyne_ros2/vlp32/1713492677464078412"),
	               tmp / "v32.rawlog", optionsFrom(v32), false);
	ASSERT_TRUE(rep.ok()) << rep.error;
	const auto c = readRawlog(tmp / "v32.rawlog");
	ASSERT_EQ(c.scans.size(), 5u);
	for (const auto& s : c.scans)
	{
		EXPECT_EQ(s->lidarModel, "VLP32C");
		EXPECT_EQ(s->rowCount, 32);
		// Per-laser azimuth offsets of up to 4.2 deg extend the sweep.
		EXPECT_GT(std::abs(s->azimuthSpan), 0.95 * 2 * M_PI);
		EXPECT_GT(core::unpackRotatingScan(*s).points.size(), 25000u);
	}
	// A packets topic with the wrong model named is refused per message.
	const std::string wrong =
	    "[bag2rawlog_lidar]\ntopic = /velodyne_packets\nlidar_model = HDL32\n"
	    "[bag2rawlog_imu]\ntopic =\n[bag2rawlog_gnss]\ntopic =\n";
	rep =
	    convertBag(sharedData("nebula_velodyne_ros2/vlp16/1673400471837873222"),
	               tmp / "w.rawlog", optionsFrom(wrong), false);
	EXPECT_FALSE(rep.ok());
	EXPECT_NE(rep.error.find("/velodyne_packets message #0"), std::string::npos)
	    << rep.error;
}

TEST(IngestBags, DamagedRos2FileIsNamed)
{
	TempDir tmp("ros2cut");
	const std::string src = sharedData(
	    "nebula_velodyne_ros2/vlp16/1673400471837873222/"
	    "1673400471837873222_0.db3");
	std::filesystem::copy_file(src, tmp / "cut.db3");
	std::filesystem::permissions(tmp / "cut.db3",
	                             std::filesystem::perms::owner_write,
	                             std::filesystem::perm_options::add);
	std::filesystem::resize_file(tmp / "cut.db3",
	                             std::filesystem::file_size(src) / 2);
	const std::string ini =
	    "[bag2rawlog_lidar]\ntopic = /velodyne_packets\n"
	    "[bag2rawlog_imu]\ntopic =\n[bag2rawlog_gnss]\ntopic =\n";
	std::string what;
	try
	{
		const auto rep = convertBag(tmp / "cut.db3", tmp / "out.rawlog",
		                            optionsFrom(ini), false);
		what = rep.error;
		// Whatever came before the damage is a valid rawlog.
		io::RawlogReader r(tmp / "out.rawlog");
		while (r.next())
		{
		}
		EXPECT_FALSE(r.damaged());
	}
	catch (const ConversionSetupError& e)
	{
		what = e.what();
	}
	EXPECT_NE(what.find("cut.db3"), std::string::npos) << what;
}
