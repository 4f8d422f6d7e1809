#include <forest_slam/ingest/messages.h>

#include <ros/serialization.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>

namespace forest_slam::ingest
{
namespace
{
// velodyne_msgs has no Debian package; these are the md5 sums rosbag records
// for velodyne_msgs/VelodyneScan (Header header, VelodynePacket[] packets).
constexpr const char* kVelodyneScanMd5 = "50804fc9533a0e579e6322c04ae70566";

template <typename RosMsg>
RosMsg deserializeRos1(const uint8_t* data, size_t size, const char* type)
{
	RosMsg m;
	try
	{
		ros::serialization::IStream s(const_cast<uint8_t*>(data),
		                              static_cast<uint32_t>(size));
		ros::serialization::deserialize(s, m);
	}
	catch (const ros::Exception& e)
	{
		throw DecodeError(std::string("cannot decode ROS 1 ") + type + " (" +
		                  std::to_string(size) + " bytes): " + e.what());
	}
	return m;
}

MsgHeader fromRos1(const std_msgs::Header& h)
{
	MsgHeader o;
	o.stamp_ns =
	    static_cast<int64_t>(h.stamp.sec) * 1000000000LL + h.stamp.nsec;
	o.frame_id = h.frame_id;
	return o;
}

MsgHeader readHeader(WireReader& r)
{
	MsgHeader h;
	if (r.wire() == Wire::Ros1) r.u32();  // seq: ROS 2 dropped it
	h.stamp_ns = r.timeNs();
	h.frame_id = r.string();
	return h;
}

template <size_t N>
void readDoubles(WireReader& r, std::array<double, N>& out)
{
	for (auto& v : out) v = r.f64();
}

template <size_t N, typename Src>
void copyArray(std::array<double, N>& out, const Src& src)
{
	std::copy(src.begin(), src.end(), out.begin());
}
}  // namespace

std::string normalizeTypeName(const std::string& type)
{
	const auto p = type.find("/msg/");
	if (p == std::string::npos) return type;
	return type.substr(0, p) + "/" + type.substr(p + 5);
}

MsgKind kindOfType(const std::string& type)
{
	const auto t = normalizeTypeName(type);
	if (t == "sensor_msgs/PointCloud2") return MsgKind::PointCloud2;
	if (t == "sensor_msgs/Imu") return MsgKind::Imu;
	if (t == "sensor_msgs/NavSatFix") return MsgKind::NavSatFix;
	if (t == "tf2_msgs/TFMessage") return MsgKind::TfMessage;
	if (t == "velodyne_msgs/VelodyneScan") return MsgKind::VelodyneScan;
	return MsgKind::Unknown;
}

const char* kindName(MsgKind k)
{
	switch (k)
	{
		case MsgKind::PointCloud2:
			return "sensor_msgs/PointCloud2";
		case MsgKind::Imu:
			return "sensor_msgs/Imu";
		case MsgKind::NavSatFix:
			return "sensor_msgs/NavSatFix";
		case MsgKind::TfMessage:
			return "tf2_msgs/TFMessage";
		case MsgKind::VelodyneScan:
			return "velodyne_msgs/VelodyneScan";
		default:
			return "unknown";
	}
}

std::string ros1Md5(MsgKind k)
{
	using namespace ros::message_traits;
	switch (k)
	{
		case MsgKind::PointCloud2:
			return MD5Sum<sensor_msgs::PointCloud2>::value();
		case MsgKind::Imu:
			return MD5Sum<sensor_msgs::Imu>::value();
		case MsgKind::NavSatFix:
			return MD5Sum<sensor_msgs::NavSatFix>::value();
		case MsgKind::TfMessage:
			return MD5Sum<tf2_msgs::TFMessage>::value();
		case MsgKind::VelodyneScan:
			return kVelodyneScanMd5;
		default:
			return "";
	}
}

PointCloud2Msg decodePointCloud2(const uint8_t* data, size_t size, Wire wire)
{
	// Both wires through WireReader: ros::serialization resizes a vector to
	// the length the message claims before checking the bytes are there
	// (a corrupt cloud asked for 1.9 GB; found by fuzz_ros_messages).
	PointCloud2Msg m;
	WireReader r(data, size, wire);
	m.header = readHeader(r);
	m.height = r.u32();
	m.width = r.u32();
	const uint32_t nf = r.arrayLength(13);
	for (uint32_t i = 0; i < nf; i++)
	{
		PointFieldDesc f;
		f.name = r.string();
		f.offset = r.u32();
		f.datatype = r.u8();
		f.count = r.u32();
		m.fields.push_back(f);
	}
	m.is_bigendian = r.boolean();
	m.point_step = r.u32();
	m.row_step = r.u32();
	const uint32_t nd = r.arrayLength(1);
	const uint8_t* p = r.bytes(nd);
	m.data.assign(p, p + nd);
	m.is_dense = r.boolean();
	return m;
}

ImuMsg decodeImu(const uint8_t* data, size_t size, Wire wire)
{
	ImuMsg m;
	if (wire == Wire::Ros1)
	{
		const auto r =
		    deserializeRos1<sensor_msgs::Imu>(data, size, "sensor_msgs/Imu");
		m.header = fromRos1(r.header);
		m.orientation_xyzw = {r.orientation.x, r.orientation.y, r.orientation.z,
		                      r.orientation.w};
		copyArray(m.orientation_covariance, r.orientation_covariance);
		m.angular_velocity = {r.angular_velocity.x, r.angular_velocity.y,
		                      r.angular_velocity.z};
		copyArray(m.angular_velocity_covariance, r.angular_velocity_covariance);
		m.linear_acceleration = {r.linear_acceleration.x,
		                         r.linear_acceleration.y,
		                         r.linear_acceleration.z};
		copyArray(m.linear_acceleration_covariance,
		          r.linear_acceleration_covariance);
		return m;
	}
	WireReader r(data, size, wire);
	m.header = readHeader(r);
	readDoubles(r, m.orientation_xyzw);
	readDoubles(r, m.orientation_covariance);
	readDoubles(r, m.angular_velocity);
	readDoubles(r, m.angular_velocity_covariance);
	readDoubles(r, m.linear_acceleration);
	readDoubles(r, m.linear_acceleration_covariance);
	return m;
}

NavSatFixMsg decodeNavSatFix(const uint8_t* data, size_t size, Wire wire)
{
	NavSatFixMsg m;
	if (wire == Wire::Ros1)
	{
		const auto r = deserializeRos1<sensor_msgs::NavSatFix>(
		    data, size, "sensor_msgs/NavSatFix");
		m.header = fromRos1(r.header);
		m.status = r.status.status;
		m.service = r.status.service;
		m.latitude_deg = r.latitude;
		m.longitude_deg = r.longitude;
		m.altitude_m = r.altitude;
		copyArray(m.position_covariance, r.position_covariance);
		m.covariance_type = r.position_covariance_type;
		return m;
	}
	WireReader r(data, size, wire);
	m.header = readHeader(r);
	m.status = r.i8();
	m.service = r.u16();
	m.latitude_deg = r.f64();
	m.longitude_deg = r.f64();
	m.altitude_m = r.f64();
	readDoubles(r, m.position_covariance);
	m.covariance_type = r.u8();
	return m;
}

TfMsg decodeTfMessage(const uint8_t* data, size_t size, Wire wire)
{
	// Both wires through WireReader, like PointCloud2: ros::serialization
	// sized the transform array from a corrupt length before checking it
	// (fuzz_ros_messages).
	TfMsg m;
	WireReader r(data, size, wire);
	const uint32_t n = r.arrayLength(8 + 4 + 4 + 56);
	for (uint32_t i = 0; i < n; i++)
	{
		TransformStampedMsg o;
		o.header = readHeader(r);
		o.child_frame_id = r.string();
		readDoubles(r, o.translation);
		readDoubles(r, o.rotation_xyzw);
		m.transforms.push_back(o);
	}
	return m;
}

VelodyneScanMsg decodeVelodyneScan(const uint8_t* data, size_t size, Wire wire)
{
	// velodyne_msgs/VelodyneScan: Header header, VelodynePacket[] packets;
	// VelodynePacket: time stamp, uint8[1206] data (fixed size: no prefix).
	WireReader r(data, size, wire);
	VelodyneScanMsg m;
	m.header = readHeader(r);
	const uint32_t n = r.arrayLength(8 + kVelodynePacketBytes);
	m.packets.resize(n);
	for (auto& p : m.packets)
	{
		p.stamp_ns = r.timeNs();
		const uint8_t* b = r.bytes(kVelodynePacketBytes);
		std::copy(b, b + kVelodynePacketBytes, p.data.begin());
	}
	return m;
}

}  // namespace forest_slam::ingest
