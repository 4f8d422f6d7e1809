#pragma once
// sensor_msgs/PointCloud2 field layouts. Every lidar driver names and types
// its per-point ring and time differently; this finds x/y/z, intensity, ring
// and time in a cloud and reads them into one plain point type, with the time
// converted to seconds relative to the header stamp.
//   Velodyne driver: ring uint16, time float32 [s] relative
//   Ouster driver:   ring uint8/uint16, t uint32 [ns] relative
//   Hesai driver:    ring uint16, timestamp float64 [s] absolute
//   nebula:          channel uint16, time_stamp uint32 [ns] relative
#include <forest_slam/ingest/messages.h>

#include <cstdint>
#include <string>
#include <vector>

namespace forest_slam::ingest
{
/** How a time field is to be read. */
enum class TimeEncoding
{
	None,
	RelativeSeconds,
	RelativeNanoseconds,
	AbsoluteSeconds,
	AbsoluteNanoseconds
};
const char* timeEncodingName(TimeEncoding e);
/** "auto", "none", "relative_s", "relative_ns", "absolute_s", "absolute_ns";
 * throws std::invalid_argument. "auto" returns None and sets `is_auto`. */
TimeEncoding parseTimeEncoding(const std::string& s, bool& is_auto);

struct CloudLayoutOptions
{
	/** Field names, or "auto" to look for the usual names, or "none". */
	std::string ring_field = "auto";
	std::string time_field = "auto";
	std::string intensity_field = "auto";
	/** "auto" decides from the field's name, type and magnitude. */
	std::string time_encoding = "auto";
};

struct FieldAccess
{
	bool present = false;
	std::string name;
	uint32_t offset = 0;
	uint8_t datatype = 0;
};

struct CloudLayout
{
	FieldAccess x, y, z, intensity, ring, time;
	TimeEncoding time_encoding = TimeEncoding::None;
	/** Relative vs absolute still to be decided from the values. */
	bool time_encoding_auto = false;
	/** e.g. "x,y,z float32; ring uint16; time float32 relative_s". */
	std::string describe() const;
};

/** Finds the fields; throws DecodeError naming the missing or malformed field
 * (x/y/z missing, field beyond point_step, data shorter than width*height*
 * point_step, unsupported datatype). */
CloudLayout analyzeCloudLayout(const PointCloud2Msg& msg,
                               const CloudLayoutOptions& opts);

struct CloudPoint
{
	float x = 0, y = 0, z = 0;
	float intensity = 0;
	uint16_t ring = 0;
	double t_s = 0;  ///< relative to the message header stamp
};

/** Reads every finite, non-zero point (drivers mark missing returns with NaN
 * or 0,0,0). Returns the number of points dropped as invalid. */
size_t extractCloudPoints(const PointCloud2Msg& msg, const CloudLayout& layout,
                          std::vector<CloudPoint>& out);

}  // namespace forest_slam::ingest
