// ROS 1 and ROS 2 (CDR) decoding of the converted message types. ROS 1 bytes
// come from the Debian message headers' own serializer; CDR bytes from an
// independent writer that follows the alignment rules.
#include <forest_slam/ingest/messages.h>

#include <gtest/gtest.h>
#include <ros/serialization.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include "test_helpers.h"

using namespace forest_slam::ingest;
using ingest_test::CdrWriter;

namespace
{
template <typename M>
std::vector<uint8_t> ros1Bytes(const M& m)
{
	std::vector<uint8_t> buf(ros::serialization::serializationLength(m));
	ros::serialization::OStream s(buf.data(),
	                              static_cast<uint32_t>(buf.size()));
	ros::serialization::serialize(s, m);
	return buf;
}

sensor_msgs::Imu sampleImu()
{
	sensor_msgs::Imu m;
	m.header.seq = 7;
	m.header.stamp = ros::Time(1700000000, 123456789);
	m.header.frame_id = "imu_link";
	m.orientation.x = 0.1;
	m.orientation.y = -0.2;
	m.orientation.z = 0.3;
	m.orientation.w = 0.9;
	for (int i = 0; i < 9; i++)
	{
		m.orientation_covariance[i] = i * 0.5;
		m.angular_velocity_covariance[i] = i * 0.25;
		m.linear_acceleration_covariance[i] = i * 0.125;
	}
	m.angular_velocity.x = 0.01;
	m.angular_velocity.y = 0.02;
	m.angular_velocity.z = -0.03;
	m.linear_acceleration.x = 0.5;
	m.linear_acceleration.y = -0.25;
	m.linear_acceleration.z = 9.81;
	return m;
}

std::vector<uint8_t> cdrImu(const sensor_msgs::Imu& m)
{
	CdrWriter w;
	w.header(static_cast<int32_t>(m.header.stamp.sec), m.header.stamp.nsec,
	         m.header.frame_id);
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

void expectImu(const ImuMsg& d, const sensor_msgs::Imu& m)
{
	EXPECT_EQ(d.header.stamp_ns, 1700000000123456789LL);
	EXPECT_EQ(d.header.frame_id, "imu_link");
	EXPECT_DOUBLE_EQ(d.orientation_xyzw[1], -0.2);
	EXPECT_DOUBLE_EQ(d.orientation_xyzw[3], 0.9);
	EXPECT_DOUBLE_EQ(d.orientation_covariance[8], 4.0);
	EXPECT_DOUBLE_EQ(d.angular_velocity[2], -0.03);
	EXPECT_DOUBLE_EQ(d.angular_velocity_covariance[3], 0.75);
	EXPECT_DOUBLE_EQ(d.linear_acceleration[2], m.linear_acceleration.z);
	EXPECT_DOUBLE_EQ(d.linear_acceleration_covariance[8], 1.0);
}
}  // namespace

TEST(IngestMessages, TypeNamesOfRos1AndRos2)
{
	EXPECT_EQ(normalizeTypeName("sensor_msgs/msg/PointCloud2"),
	          "sensor_msgs/PointCloud2");
	EXPECT_EQ(kindOfType("sensor_msgs/msg/Imu"), MsgKind::Imu);
	EXPECT_EQ(kindOfType("sensor_msgs/NavSatFix"), MsgKind::NavSatFix);
	EXPECT_EQ(kindOfType("velodyne_msgs/msg/VelodyneScan"),
	          MsgKind::VelodyneScan);
	EXPECT_EQ(kindOfType("tf2_msgs/TFMessage"), MsgKind::TfMessage);
	EXPECT_EQ(kindOfType("sensor_msgs/LaserScan"), MsgKind::Unknown);
	EXPECT_EQ(ros1Md5(MsgKind::Imu), "6a62c6daae103f4ff57a132d6f95cec2");
}

TEST(IngestMessages, ImuRos1AndCdrDecodeAlike)
{
	const auto m = sampleImu();
	const auto a = ros1Bytes(m);
	expectImu(decodeImu(a.data(), a.size(), Wire::Ros1), m);
	const auto b = cdrImu(m);
	expectImu(decodeImu(b.data(), b.size(), Wire::Cdr), m);
}

TEST(IngestMessages, BigEndianCdrIsSwapped)
{
	// Build the big-endian payload by swapping every primitive of the LE one
	// through a parallel writer.
	const auto m = sampleImu();
	std::vector<uint8_t> be = {0x00, 0x00, 0x00, 0x00};
	auto align = [&](size_t n)
	{
		while ((be.size() - 4) % n) be.push_back(0);
	};
	auto put = [&](auto v)
	{
		align(sizeof(v));
		uint8_t b[sizeof(v)];
		std::memcpy(b, &v, sizeof(v));
		for (size_t i = sizeof(v); i-- > 0;) be.push_back(b[i]);
	};
	put(static_cast<int32_t>(m.header.stamp.sec));
	put(static_cast<uint32_t>(m.header.stamp.nsec));
	put(static_cast<uint32_t>(m.header.frame_id.size() + 1));
	for (char c : m.header.frame_id) be.push_back(static_cast<uint8_t>(c));
	be.push_back(0);
	for (double v :
	     {m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w})
		put(v);
	for (double v : m.orientation_covariance) put(v);
	for (double v :
	     {m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z})
		put(v);
	for (double v : m.angular_velocity_covariance) put(v);
	for (double v : {m.linear_acceleration.x, m.linear_acceleration.y,
	                 m.linear_acceleration.z})
		put(v);
	for (double v : m.linear_acceleration_covariance) put(v);
	expectImu(decodeImu(be.data(), be.size(), Wire::Cdr), m);
}

TEST(IngestMessages, NavSatFixAlignmentAfterInt8Status)
{
	sensor_msgs::NavSatFix m;
	m.header.stamp = ros::Time(1600000000, 5);
	m.header.frame_id = "gps";  // 4 chars: string ends unaligned for the int8
	m.status.status = sensor_msgs::NavSatStatus::STATUS_GBAS_FIX;
	m.status.service = sensor_msgs::NavSatStatus::SERVICE_GPS |
	                   sensor_msgs::NavSatStatus::SERVICE_GALILEO;
	m.latitude = 60.123456789;
	m.longitude = 10.987654321;
	m.altitude = 123.5;
	for (int i = 0; i < 9; i++) m.position_covariance[i] = 0.01 * (i + 1);
	m.position_covariance_type = sensor_msgs::NavSatFix::COVARIANCE_TYPE_KNOWN;

	CdrWriter w;
	w.header(1600000000, 5, "gps");
	w.put<int8_t>(m.status.status);
	w.put<uint16_t>(m.status.service);
	w.put<double>(m.latitude);
	w.put<double>(m.longitude);
	w.put<double>(m.altitude);
	for (double v : m.position_covariance) w.put<double>(v);
	w.put<uint8_t>(m.position_covariance_type);

	const auto a = ros1Bytes(m);
	for (const auto& [bytes, wire] :
	     {std::make_pair(a, Wire::Ros1), std::make_pair(w.data(), Wire::Cdr)})
	{
		const auto d = decodeNavSatFix(bytes.data(), bytes.size(), wire);
		EXPECT_EQ(d.header.stamp_ns, 1600000000000000005LL);
		EXPECT_EQ(d.status, 2);
		EXPECT_EQ(d.service, 9);
		EXPECT_DOUBLE_EQ(d.latitude_deg, 60.123456789);
		EXPECT_DOUBLE_EQ(d.longitude_deg, 10.987654321);
		EXPECT_DOUBLE_EQ(d.altitude_m, 123.5);
		EXPECT_DOUBLE_EQ(d.position_covariance[8], 0.09);
		EXPECT_EQ(d.covariance_type, 3);
	}
}

TEST(IngestMessages, PointCloud2BothWires)
{
	sensor_msgs::PointCloud2 m;
	m.header.stamp = ros::Time(1500000000, 250000000);
	m.header.frame_id = "velodyne";
	m.height = 1;
	m.width = 2;
	const char* names[] = {"x", "y", "z", "intensity", "ring", "time"};
	const uint32_t offs[] = {0, 4, 8, 12, 16, 18};
	const uint8_t types[] = {7, 7, 7, 7, 4, 7};
	for (int i = 0; i < 6; i++)
	{
		sensor_msgs::PointField f;
		f.name = names[i];
		f.offset = offs[i];
		f.datatype = types[i];
		f.count = 1;
		m.fields.push_back(f);
	}
	m.point_step = 22;
	m.row_step = 44;
	m.data.resize(44);
	for (size_t i = 0; i < m.data.size(); i++)
		m.data[i] = static_cast<uint8_t>(i * 7);
	m.is_dense = true;

	CdrWriter w;
	w.header(1500000000, 250000000, "velodyne");
	w.put<uint32_t>(1);
	w.put<uint32_t>(2);
	w.put<uint32_t>(6);
	for (int i = 0; i < 6; i++)
	{
		w.str(names[i]);
		w.put<uint32_t>(offs[i]);
		w.put<uint8_t>(types[i]);
		w.put<uint32_t>(1);
	}
	w.put<uint8_t>(0);
	w.put<uint32_t>(22);
	w.put<uint32_t>(44);
	w.put<uint32_t>(44);
	w.bytes(m.data.data(), 44);
	w.put<uint8_t>(1);

	const auto a = ros1Bytes(m);
	for (const auto& [bytes, wire] :
	     {std::make_pair(a, Wire::Ros1), std::make_pair(w.data(), Wire::Cdr)})
	{
		const auto d = decodePointCloud2(bytes.data(), bytes.size(), wire);
		EXPECT_EQ(d.header.stamp_ns, 1500000000250000000LL);
		EXPECT_EQ(d.header.frame_id, "velodyne");
		ASSERT_EQ(d.fields.size(), 6u);
		EXPECT_EQ(d.fields[4].name, "ring");
		EXPECT_EQ(d.fields[4].offset, 16u);
		EXPECT_EQ(d.fields[4].datatype, 4);
		EXPECT_EQ(d.point_step, 22u);
		EXPECT_EQ(d.width, 2u);
		EXPECT_EQ(d.data, m.data);
		EXPECT_TRUE(d.is_dense);
	}
}

TEST(IngestMessages, TfMessageBothWires)
{
	tf2_msgs::TFMessage m;
	for (int i = 0; i < 2; i++)
	{
		geometry_msgs::TransformStamped t;
		t.header.stamp = ros::Time(10 + i, 0);
		t.header.frame_id = "base_link";
		t.child_frame_id = i ? "imu_link" : "velodyne";
		t.transform.translation.x = 0.1 * (i + 1);
		t.transform.translation.z = 0.5;
		t.transform.rotation.z = std::sin(0.25);
		t.transform.rotation.w = std::cos(0.25);
		m.transforms.push_back(t);
	}
	CdrWriter w;
	w.put<uint32_t>(2);
	for (const auto& t : m.transforms)
	{
		w.header(static_cast<int32_t>(t.header.stamp.sec), 0,
		         t.header.frame_id);
		w.str(t.child_frame_id);
		for (double v : {t.transform.translation.x, t.transform.translation.y,
		                 t.transform.translation.z, t.transform.rotation.x,
		                 t.transform.rotation.y, t.transform.rotation.z,
		                 t.transform.rotation.w})
			w.put<double>(v);
	}
	const auto a = ros1Bytes(m);
	for (const auto& [bytes, wire] :
	     {std::make_pair(a, Wire::Ros1), std::make_pair(w.data(), Wire::Cdr)})
	{
		const auto d = decodeTfMessage(bytes.data(), bytes.size(), wire);
		ASSERT_EQ(d.transforms.size(), 2u);
		EXPECT_EQ(d.transforms[1].child_frame_id, "imu_link");
		EXPECT_EQ(d.transforms[1].header.frame_id, "base_link");
		EXPECT_DOUBLE_EQ(d.transforms[1].translation[0], 0.2);
		EXPECT_DOUBLE_EQ(d.transforms[0].rotation_xyzw[3], std::cos(0.25));
	}
}

TEST(IngestMessages, VelodyneScanRos1RawBytesAndCdr)
{
	// velodyne_msgs has no Debian package: build the ROS 1 bytes by hand
	// (Header{seq, stamp, frame_id}, uint32 count, {time, uint8[1206]}...).
	std::vector<uint8_t> r1;
	auto put32 = [&](uint32_t v)
	{
		for (int i = 0; i < 4; i++)
			r1.push_back(static_cast<uint8_t>(v >> (8 * i)));
	};
	put32(3);
	put32(100);
	put32(7);
	put32(8);
	for (char c : std::string("velodyne"))
		r1.push_back(static_cast<uint8_t>(c));
	put32(2);
	CdrWriter w;
	w.header(100, 7, "velodyne");
	w.put<uint32_t>(2);
	for (uint32_t k = 0; k < 2; k++)
	{
		put32(100);
		put32(1000 + k);
		w.time(100, 1000 + k);
		std::vector<uint8_t> pkt(kVelodynePacketBytes);
		for (size_t i = 0; i < pkt.size(); i++)
			pkt[i] = static_cast<uint8_t>(i + 3 * k);
		r1.insert(r1.end(), pkt.begin(), pkt.end());
		w.bytes(pkt.data(), pkt.size());
	}
	for (const auto& [bytes, wire] :
	     {std::make_pair(r1, Wire::Ros1), std::make_pair(w.data(), Wire::Cdr)})
	{
		const auto d = decodeVelodyneScan(bytes.data(), bytes.size(), wire);
		EXPECT_EQ(d.header.frame_id, "velodyne");
		EXPECT_EQ(d.header.stamp_ns, 100000000007LL);
		ASSERT_EQ(d.packets.size(), 2u);
		EXPECT_EQ(d.packets[1].stamp_ns, 100000001001LL);
		EXPECT_EQ(d.packets[1].data[0], 3);
		EXPECT_EQ(d.packets[1].data[1205], static_cast<uint8_t>(1205 + 3));
	}
}

TEST(IngestMessages, DamagedPayloadsThrowWithContext)
{
	const auto m = sampleImu();
	auto b = cdrImu(m);
	b.resize(b.size() - 3);
	try
	{
		decodeImu(b.data(), b.size(), Wire::Cdr);
		FAIL() << "truncated CDR accepted";
	}
	catch (const DecodeError& e)
	{
		EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos)
		    << e.what();
	}
	auto a = ros1Bytes(m);
	a.resize(40);
	EXPECT_THROW(decodeImu(a.data(), a.size(), Wire::Ros1), DecodeError);
	// Parameter-list CDR is not what rosbag2 stores for plain messages.
	auto pl = cdrImu(m);
	pl[1] = 0x03;
	EXPECT_THROW(decodeImu(pl.data(), pl.size(), Wire::Cdr), DecodeError);
	// An array count larger than the bytes left.
	CdrWriter w;
	w.put<uint32_t>(1000000);
	EXPECT_THROW(decodeTfMessage(w.data().data(), w.data().size(), Wire::Cdr),
	             DecodeError);
}
