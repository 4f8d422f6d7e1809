#pragma once
// The ROS message types bag2rawlog converts, as plain structs independent of
// the ROS version, and their decoders from serialized bytes. ROS 1 messages
// go through the Debian sensor_msgs / tf2_msgs headers (the reference
// serialization); ROS 2 (CDR) and velodyne_msgs (no Debian headers) use
// WireReader, following the .msg definitions field by field.
#include <forest_slam/ingest/wire.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace forest_slam::ingest
{
struct MsgHeader
{
	int64_t stamp_ns = 0;
	std::string frame_id;
};

/** sensor_msgs/PointField; datatype codes as in the message (1=INT8 ..
 * 8=FLOAT64). */
struct PointFieldDesc
{
	std::string name;
	uint32_t offset = 0;
	uint8_t datatype = 0;
	uint32_t count = 1;
};

struct PointCloud2Msg
{
	MsgHeader header;
	uint32_t height = 0, width = 0;
	std::vector<PointFieldDesc> fields;
	bool is_bigendian = false;
	uint32_t point_step = 0, row_step = 0;
	std::vector<uint8_t> data;
	bool is_dense = false;
};

struct ImuMsg
{
	MsgHeader header;
	std::array<double, 4> orientation_xyzw{0, 0, 0, 1};
	std::array<double, 9> orientation_covariance{};
	std::array<double, 3> angular_velocity{};
	std::array<double, 9> angular_velocity_covariance{};
	std::array<double, 3> linear_acceleration{};
	std::array<double, 9> linear_acceleration_covariance{};
};

struct NavSatFixMsg
{
	MsgHeader header;
	int8_t status = -1;  ///< -1 no fix, 0 fix, 1 SBAS, 2 GBAS
	uint16_t service = 0;
	double latitude_deg = 0, longitude_deg = 0, altitude_m = 0;
	std::array<double, 9> position_covariance{};  ///< ENU, m^2, row-major
	uint8_t covariance_type = 0;  ///< 0 unknown, 1 approx., 2 diag., 3 known
};

struct TransformStampedMsg
{
	MsgHeader header;  ///< frame_id = parent
	std::string child_frame_id;
	std::array<double, 3> translation{};
	std::array<double, 4> rotation_xyzw{0, 0, 0, 1};
};

struct TfMsg
{
	std::vector<TransformStampedMsg> transforms;
};

constexpr size_t kVelodynePacketBytes = 1206;
struct VelodynePacketMsg
{
	int64_t stamp_ns = 0;
	std::array<uint8_t, kVelodynePacketBytes> data{};
};

struct VelodyneScanMsg
{
	MsgHeader header;
	std::vector<VelodynePacketMsg> packets;
};

/** The message types bag2rawlog knows. */
enum class MsgKind
{
	PointCloud2,
	Imu,
	NavSatFix,
	TfMessage,
	VelodyneScan,
	Unknown
};

/** "sensor_msgs/msg/Imu" and "sensor_msgs/Imu" both give "sensor_msgs/Imu". */
std::string normalizeTypeName(const std::string& type);
MsgKind kindOfType(const std::string& type);
const char* kindName(MsgKind k);

/** Decoders; throw DecodeError on any mismatch (truncated, trailing bytes
 * are tolerated as ROS does). */
PointCloud2Msg decodePointCloud2(const uint8_t* data, size_t size, Wire wire);
ImuMsg decodeImu(const uint8_t* data, size_t size, Wire wire);
NavSatFixMsg decodeNavSatFix(const uint8_t* data, size_t size, Wire wire);
TfMsg decodeTfMessage(const uint8_t* data, size_t size, Wire wire);
VelodyneScanMsg decodeVelodyneScan(const uint8_t* data, size_t size, Wire wire);

/** MD5 sums of the ROS 1 definitions, to reject a topic whose recorded type
 * has the right name but another layout. Empty for unknown kinds. */
std::string ros1Md5(MsgKind k);

}  // namespace forest_slam::ingest
