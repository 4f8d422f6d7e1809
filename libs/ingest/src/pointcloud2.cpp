#include <forest_slam/ingest/pointcloud2.h>

#include <cmath>
#include <cstring>
#include <stdexcept>

namespace forest_slam::ingest
{
namespace
{
// sensor_msgs/PointField datatype codes.
enum : uint8_t
{
	kInt8 = 1,
	kUint8 = 2,
	kInt16 = 3,
	kUint16 = 4,
	kInt32 = 5,
	kUint32 = 6,
	kFloat32 = 7,
	kFloat64 = 8
};

size_t typeSize(uint8_t t)
{
	switch (t)
	{
		case kInt8:
		case kUint8:
			return 1;
		case kInt16:
		case kUint16:
			return 2;
		case kInt32:
		case kUint32:
		case kFloat32:
			return 4;
		case kFloat64:
			return 8;
		default:
			return 0;
	}
}

const char* typeName(uint8_t t)
{
	static const char* names[] = {"?",      "int8",    "uint8",
	                              "int16",  "uint16",  "int32",
	                              "uint32", "float32", "float64"};
	return t <= 8 ? names[t] : "?";
}

template <typename T>
T load(const uint8_t* p, bool swap)
{
	uint8_t b[sizeof(T)];
	std::memcpy(b, p, sizeof(T));
	if (swap)
		for (size_t i = 0; i < sizeof(T) / 2; i++)
			std::swap(b[i], b[sizeof(T) - 1 - i]);
	T v;
	std::memcpy(&v, b, sizeof(T));
	return v;
}

double readValue(const uint8_t* p, uint8_t type, bool swap)
{
	switch (type)
	{
		case kInt8:
			return static_cast<int8_t>(*p);
		case kUint8:
			return *p;
		case kInt16:
			return load<int16_t>(p, swap);
		case kUint16:
			return load<uint16_t>(p, swap);
		case kInt32:
			return load<int32_t>(p, swap);
		case kUint32:
			return load<uint32_t>(p, swap);
		case kFloat32:
			return load<float>(p, swap);
		case kFloat64:
			return load<double>(p, swap);
		default:
			return 0;
	}
}

const PointFieldDesc* findField(const PointCloud2Msg& m,
                                const std::string& name)
{
	for (const auto& f : m.fields)
		if (f.name == name) return &f;
	return nullptr;
}

FieldAccess access(const PointCloud2Msg& m, const PointFieldDesc* f)
{
	FieldAccess a;
	if (!f) return a;
	const size_t sz = typeSize(f->datatype);
	if (sz == 0)
		throw DecodeError("PointCloud2 field '" + f->name +
		                  "' has unknown datatype " +
		                  std::to_string(static_cast<int>(f->datatype)));
	if (f->offset + sz > m.point_step)
		throw DecodeError("PointCloud2 field '" + f->name + "' (offset " +
		                  std::to_string(f->offset) + ", " +
		                  typeName(f->datatype) + ") lies beyond point_step " +
		                  std::to_string(m.point_step));
	a.present = true;
	a.name = f->name;
	a.offset = f->offset;
	a.datatype = f->datatype;
	return a;
}

/** First of `candidates` present in the cloud, or the explicit name. */
FieldAccess pick(const PointCloud2Msg& m, const std::string& option,
                 const std::vector<std::string>& candidates, const char* role)
{
	if (option == "none") return {};
	if (option != "auto")
	{
		const auto* f = findField(m, option);
		if (!f)
		{
			std::string have;
			for (const auto& g : m.fields)
				have += (have.empty() ? "" : ",") + g.name;
			throw DecodeError(std::string("PointCloud2 has no ") + role +
			                  " field '" + option + "' (fields: " + have + ")");
		}
		return access(m, f);
	}
	for (const auto& c : candidates)
		if (const auto* f = findField(m, c)) return access(m, f);
	return {};
}
}  // namespace

const char* timeEncodingName(TimeEncoding e)
{
	switch (e)
	{
		case TimeEncoding::None:
			return "none";
		case TimeEncoding::RelativeSeconds:
			return "relative_s";
		case TimeEncoding::RelativeNanoseconds:
			return "relative_ns";
		case TimeEncoding::AbsoluteSeconds:
			return "absolute_s";
		case TimeEncoding::AbsoluteNanoseconds:
			return "absolute_ns";
	}
	return "?";
}

TimeEncoding parseTimeEncoding(const std::string& s, bool& is_auto)
{
	is_auto = s == "auto";
	if (is_auto || s == "none") return TimeEncoding::None;
	for (auto e :
	     {TimeEncoding::RelativeSeconds, TimeEncoding::RelativeNanoseconds,
	      TimeEncoding::AbsoluteSeconds, TimeEncoding::AbsoluteNanoseconds})
		if (s == timeEncodingName(e)) return e;
	throw std::invalid_argument(
	    "time encoding '" + s +
	    "' is not one of auto, none, relative_s, relative_ns, absolute_s, "
	    "absolute_ns");
}

std::string CloudLayout::describe() const
{
	auto f = [](const FieldAccess& a)
	{ return a.name + " " + typeName(a.datatype); };
	std::string s = "x,y,z " + std::string(typeName(x.datatype));
	s += intensity.present ? "; intensity=" + f(intensity) : "; no intensity";
	s += ring.present ? "; ring=" + f(ring) : "; no ring";
	s += time.present
	         ? "; time=" + f(time) + " " + timeEncodingName(time_encoding)
	         : "; no per-point time";
	return s;
}

CloudLayout analyzeCloudLayout(const PointCloud2Msg& m,
                               const CloudLayoutOptions& o)
{
	CloudLayout L;
	L.x = access(m, findField(m, "x"));
	L.y = access(m, findField(m, "y"));
	L.z = access(m, findField(m, "z"));
	if (!L.x.present || !L.y.present || !L.z.present)
	{
		std::string have;
		for (const auto& g : m.fields)
			have += (have.empty() ? "" : ",") + g.name;
		throw DecodeError("PointCloud2 lacks x/y/z fields (fields: " + have +
		                  ")");
	}
	L.intensity = pick(m, o.intensity_field, {"intensity", "reflectivity", "i"},
	                   "intensity");
	L.ring =
	    pick(m, o.ring_field, {"ring", "channel", "laser_id", "line"}, "ring");
	L.time =
	    pick(m, o.time_field,
	         {"time", "t", "timestamp", "time_stamp", "offset_time"}, "time");
	bool is_auto = false;
	L.time_encoding = parseTimeEncoding(o.time_encoding, is_auto);
	L.time_encoding_auto = is_auto;
	if (!is_auto && L.time_encoding == TimeEncoding::None) L.time = {};
	if (L.time.present && is_auto)
	{
		// Integer time fields count nanoseconds (Ouster t, nebula time_stamp,
		// Livox offset_time); float fields count seconds. Relative versus
		// absolute is decided from the values in extractCloudPoints().
		const bool integer =
		    L.time.datatype != kFloat32 && L.time.datatype != kFloat64;
		L.time_encoding = integer ? TimeEncoding::RelativeNanoseconds
		                          : TimeEncoding::RelativeSeconds;
	}
	if (!L.time.present) L.time_encoding = TimeEncoding::None;
	return L;
}

size_t extractCloudPoints(const PointCloud2Msg& m, const CloudLayout& L,
                          std::vector<CloudPoint>& out)
{
	out.clear();
	const uint64_t n = static_cast<uint64_t>(m.width) * m.height;
	// No point: nothing to read (width 0 with height 4e9 looped for
	// seconds over empty rows; fuzz_ros_messages).
	if (n == 0) return 0;
	if (m.point_step == 0) throw DecodeError("PointCloud2 has point_step 0");
	const uint64_t row_bytes = static_cast<uint64_t>(m.width) * m.point_step;
	const uint64_t row_step = m.row_step ? m.row_step : row_bytes;
	if (row_step < row_bytes)
		throw DecodeError("PointCloud2 row_step " + std::to_string(m.row_step) +
		                  " < width*point_step " + std::to_string(row_bytes));
	if (m.height > 0 && (m.height - 1) * row_step + row_bytes > m.data.size())
		throw DecodeError("PointCloud2 data has " +
		                  std::to_string(m.data.size()) + " bytes, width " +
		                  std::to_string(m.width) + " x height " +
		                  std::to_string(m.height) + " x point_step " +
		                  std::to_string(m.point_step) + " needs more");
	const bool swap = m.is_bigendian;  // we only run on little-endian hosts
	const double stamp_s = m.header.stamp_ns * 1e-9;
	out.reserve(n);
	size_t invalid = 0;
	// Absolute or relative: a time value near the header stamp is absolute.
	TimeEncoding enc = L.time_encoding;
	bool decided = !L.time_encoding_auto;
	for (uint32_t row = 0; row < m.height; row++)
	{
		const uint8_t* base = m.data.data() + row * row_step;
		for (uint32_t col = 0; col < m.width; col++)
		{
			const uint8_t* p = base + static_cast<size_t>(col) * m.point_step;
			CloudPoint q;
			q.x = static_cast<float>(
			    readValue(p + L.x.offset, L.x.datatype, swap));
			q.y = static_cast<float>(
			    readValue(p + L.y.offset, L.y.datatype, swap));
			q.z = static_cast<float>(
			    readValue(p + L.z.offset, L.z.datatype, swap));
			if (!std::isfinite(q.x) || !std::isfinite(q.y) ||
			    !std::isfinite(q.z) || (q.x == 0 && q.y == 0 && q.z == 0))
			{
				invalid++;
				continue;
			}
			if (L.intensity.present)
				q.intensity = static_cast<float>(readValue(
				    p + L.intensity.offset, L.intensity.datatype, swap));
			if (L.ring.present)
			{
				const double r =
				    readValue(p + L.ring.offset, L.ring.datatype, swap);
				if (!(r >= 0 && r < 65536))
					throw DecodeError("PointCloud2 point " +
					                  std::to_string(out.size()) +
					                  " has ring " + std::to_string(r));
				q.ring = static_cast<uint16_t>(r);
			}
			if (L.time.present)
			{
				const double v =
				    readValue(p + L.time.offset, L.time.datatype, swap);
				if (!decided)
				{
					const bool ns = enc == TimeEncoding::RelativeNanoseconds ||
					                enc == TimeEncoding::AbsoluteNanoseconds;
					const double v_s = ns ? v * 1e-9 : v;
					// A relative offset is at most seconds; an absolute one is
					// within a day of the header stamp (1e4 s covers clock
					// offsets of misconfigured drivers too).
					if (enc == TimeEncoding::RelativeSeconds ||
					    enc == TimeEncoding::RelativeNanoseconds)
					{
						if (std::abs(v_s) > 1e6 &&
						    std::abs(v_s - stamp_s) < 1e5)
							enc = ns ? TimeEncoding::AbsoluteNanoseconds
							         : TimeEncoding::AbsoluteSeconds;
					}
					decided = true;
				}
				switch (enc)
				{
					case TimeEncoding::RelativeSeconds:
						q.t_s = v;
						break;
					case TimeEncoding::RelativeNanoseconds:
						q.t_s = v * 1e-9;
						break;
					case TimeEncoding::AbsoluteSeconds:
						q.t_s = v - stamp_s;
						break;
					case TimeEncoding::AbsoluteNanoseconds:
						q.t_s =
						    (v - static_cast<double>(m.header.stamp_ns)) * 1e-9;
						break;
					default:
						break;
				}
			}
			out.push_back(q);
		}
	}
	return invalid;
}

}  // namespace forest_slam::ingest
