// LAS / PLY / PCD readers for the standalone tree mode. Byte layouts follow the
// ASPRS LAS 1.4 R15 specification (tables 3, 7–16), the PLY format of Turk
// (1994) and the PCL PCD v0.7 description.
#include <forest_slam/io/las.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>

namespace forest_slam::io
{
namespace
{
std::vector<char> slurp(const std::string& path)
{
	std::ifstream f(path, std::ios::binary);
	if (!f) throw CloudFileError(path + ": cannot open");
	std::vector<char> d((std::istreambuf_iterator<char>(f)),
	                    std::istreambuf_iterator<char>());
	if (f.bad()) throw CloudFileError(path + ": read error");
	return d;
}

template <typename T>
T get(const std::vector<char>& d, size_t off)
{
	T v;
	std::memcpy(&v, d.data() + off, sizeof(T));  // little-endian hosts only
	return v;
}

[[noreturn]] void fail(const std::string& path, size_t offset,
                       const std::string& what)
{
	throw CloudFileError(path + ": byte " + std::to_string(offset) + ": " +
	                     what);
}

std::string lower(std::string s)
{
	for (auto& c : s)
		c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
	return s;
}

// Scalar types shared by PLY and PCD headers.
enum class Scalar
{
	I8,
	U8,
	I16,
	U16,
	I32,
	U32,
	I64,
	U64,
	F32,
	F64
};

size_t scalarSize(Scalar s)
{
	switch (s)
	{
		case Scalar::I8:
		case Scalar::U8:
			return 1;
		case Scalar::I16:
		case Scalar::U16:
			return 2;
		case Scalar::I32:
		case Scalar::U32:
		case Scalar::F32:
			return 4;
		default:
			return 8;
	}
}

double readScalar(const char* p, Scalar s)
{
	switch (s)
	{
		case Scalar::I8:
		{
			int8_t v;
			std::memcpy(&v, p, 1);
			return v;
		}
		case Scalar::U8:
		{
			uint8_t v;
			std::memcpy(&v, p, 1);
			return v;
		}
		case Scalar::I16:
		{
			int16_t v;
			std::memcpy(&v, p, 2);
			return v;
		}
		case Scalar::U16:
		{
			uint16_t v;
			std::memcpy(&v, p, 2);
			return v;
		}
		case Scalar::I32:
		{
			int32_t v;
			std::memcpy(&v, p, 4);
			return v;
		}
		case Scalar::U32:
		{
			uint32_t v;
			std::memcpy(&v, p, 4);
			return v;
		}
		case Scalar::I64:
		{
			int64_t v;
			std::memcpy(&v, p, 8);
			return double(v);
		}
		case Scalar::U64:
		{
			uint64_t v;
			std::memcpy(&v, p, 8);
			return double(v);
		}
		case Scalar::F32:
		{
			float v;
			std::memcpy(&v, p, 4);
			return v;
		}
		default:
		{
			double v;
			std::memcpy(&v, p, 8);
			return v;
		}
	}
}

bool plyScalar(const std::string& name, Scalar& s)
{
	static const std::pair<const char*, Scalar> k[] = {
	    {"char", Scalar::I8},    {"int8", Scalar::I8},
	    {"uchar", Scalar::U8},   {"uint8", Scalar::U8},
	    {"short", Scalar::I16},  {"int16", Scalar::I16},
	    {"ushort", Scalar::U16}, {"uint16", Scalar::U16},
	    {"int", Scalar::I32},    {"int32", Scalar::I32},
	    {"uint", Scalar::U32},   {"uint32", Scalar::U32},
	    {"float", Scalar::F32},  {"float32", Scalar::F32},
	    {"double", Scalar::F64}, {"float64", Scalar::F64}};
	for (const auto& [n, v] : k)
		if (name == n)
		{
			s = v;
			return true;
		}
	return false;
}

struct Field
{
	std::string name;
	Scalar type = Scalar::F32;
	size_t offset = 0;  ///< within a binary record
	size_t count = 1;   ///< PCD COUNT
	size_t column = 0;  ///< first ascii column
};

/** Splits the header (lines up to and including `last_key`) off the data. */
size_t headerEnd(const std::vector<char>& d, const std::string& path,
                 const std::string& last_key, std::vector<std::string>& lines)
{
	size_t pos = 0;
	while (pos < d.size())
	{
		const auto nl = std::find(d.begin() + pos, d.end(), '\n');
		if (nl == d.end()) break;
		std::string line(d.begin() + pos, nl);
		if (!line.empty() && line.back() == '\r') line.pop_back();
		pos = static_cast<size_t>(nl - d.begin()) + 1;
		lines.push_back(line);
		std::istringstream is(line);
		std::string key;
		is >> key;
		if (lower(key) == last_key) return pos;
		if (lines.size() > 10000) break;
	}
	fail(path, pos, "header has no '" + last_key + "' line");
}

const Field* findField(const std::vector<Field>& f, const std::string& name)
{
	for (const auto& x : f)
		if (x.name == name) return &x;
	return nullptr;
}

void requireXyz(const std::vector<Field>& f, const std::string& path)
{
	for (const char* n : {"x", "y", "z"})
	{
		const auto* x = findField(f, n);
		if (!x) throw CloudFileError(path + ": no '" + n + "' field");
		if (x->type != Scalar::F32 && x->type != Scalar::F64)
			throw CloudFileError(path + ": field '" + n +
			                     "' must be float or double");
	}
}

/** Reads `n` records of `fields` from ascii lines or binary records. */
void readRecords(const std::vector<char>& d, size_t start, size_t n,
                 const std::vector<Field>& fields, size_t record_size,
                 bool binary, bool drop_nan, const std::string& path,
                 PointCloudFile& out)
{
	const Field* fx = findField(fields, "x");
	const Field* fy = findField(fields, "y");
	const Field* fz = findField(fields, "z");
	const Field* fi = findField(fields, "intensity");
	out.xyz.reserve(n);
	if (fi) out.intensity.reserve(n);
	auto push = [&](double x, double y, double z, double i)
	{
		if (drop_nan &&
		    !(std::isfinite(x) && std::isfinite(y) && std::isfinite(z)))
			return;
		out.xyz.emplace_back(x, y, z);
		if (fi)
			out.intensity.push_back(static_cast<uint16_t>(
			    std::clamp(std::isfinite(i) ? i : 0.0, 0.0, 65535.0)));
	};
	if (binary)
	{
		if (start + n * record_size > d.size())
			fail(path, d.size(),
			     "file truncated: " + std::to_string(n) + " points of " +
			         std::to_string(record_size) + " bytes need " +
			         std::to_string(start + n * record_size) + " bytes");
		for (size_t k = 0; k < n; k++)
		{
			const char* r = d.data() + start + k * record_size;
			push(readScalar(r + fx->offset, fx->type),
			     readScalar(r + fy->offset, fy->type),
			     readScalar(r + fz->offset, fz->type),
			     fi ? readScalar(r + fi->offset, fi->type) : 0.0);
		}
		return;
	}
	size_t ncols = 0;
	for (const auto& f : fields) ncols = std::max(ncols, f.column + f.count);
	size_t pos = start;
	std::vector<double> v(ncols);
	for (size_t k = 0; k < n; k++)
	{
		if (pos >= d.size())
			fail(path, pos,
			     "file truncated: expected " + std::to_string(n) +
			         " points, found " + std::to_string(k));
		const auto nl = std::find(d.begin() + pos, d.end(), '\n');
		const std::string line(d.begin() + pos, nl);
		const size_t line_start = pos;
		pos = static_cast<size_t>(nl - d.begin()) + (nl == d.end() ? 0 : 1);
		if (nl == d.end()) pos = d.size();
		std::istringstream is(line);
		for (size_t c = 0; c < ncols; c++)
		{
			std::string tok;
			if (!(is >> tok))
				fail(path, line_start,
				     "point " + std::to_string(k) + " has fewer than " +
				         std::to_string(ncols) + " values");
			if (tok == "nan" || tok == "NaN" || tok == "-nan")
				v[c] = std::numeric_limits<double>::quiet_NaN();
			else
			{
				char* end = nullptr;
				v[c] = std::strtod(tok.c_str(), &end);
				if (end == tok.c_str() || *end)
					fail(path, line_start,
					     "point " + std::to_string(k) + ": bad number '" + tok +
					         "'");
			}
		}
		push(v[fx->column], v[fy->column], v[fz->column],
		     fi ? v[fi->column] : 0.0);
	}
}
}  // namespace

PointCloudFile readLas(const std::string& path, bool partial)
{
	return parseLas(slurp(path), path, partial);
}

PointCloudFile parseLas(const std::vector<char>& d, const std::string& path,
                        bool partial)
{
	if (d.size() < 227)
		fail(path, d.size(), "shorter than a LAS 1.2 header (227 bytes)");
	if (std::memcmp(d.data(), "LASF", 4) != 0)
		fail(path, 0, "bad signature (expected 'LASF')");
	const int major = static_cast<uint8_t>(d[24]),
	          minor = static_cast<uint8_t>(d[25]);
	if (major != 1 || minor < 2 || minor > 4)
		fail(path, 24,
		     "unsupported LAS version " + std::to_string(major) + "." +
		         std::to_string(minor) + " (1.2–1.4 are read)");
	const auto header_size = get<uint16_t>(d, 94);
	const auto point_offset = get<uint32_t>(d, 96);
	const uint8_t format_raw = static_cast<uint8_t>(d[104]);
	const auto record_len = get<uint16_t>(d, 105);
	if (format_raw & 0xC0)
		fail(path, 104,
		     "compressed (LAZ) point data is not supported; decompress with "
		     "laszip first");
	const int format = format_raw & 0x3F;
	static const int kMinLen[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
	if (!(format <= 3 || (format >= 6 && format <= 8)))
		fail(path, 104,
		     "point data format " + std::to_string(format) +
		         " not supported (0–3 and 6–8 are read)");
	if (record_len < kMinLen[format])
		fail(path, 105,
		     "point record length " + std::to_string(record_len) +
		         " is shorter than format " + std::to_string(format) +
		         " needs (" + std::to_string(kMinLen[format]) + ")");
	if (header_size < 227 || header_size > d.size())
		fail(path, 94, "invalid header size " + std::to_string(header_size));
	uint64_t n = get<uint32_t>(d, 107);
	if (minor == 4)
	{
		if (d.size() < 375 || header_size < 375)
			fail(path, 94, "LAS 1.4 header shorter than 375 bytes");
		const auto n64 = get<uint64_t>(d, 247);
		// 1.4 writers set the legacy count to 0 for formats >= 6.
		if (n64 != 0) n = n64;
	}
	if (point_offset < header_size)
		fail(path, 96,
		     "offset to point data (" + std::to_string(point_offset) +
		         ") lies inside the header");
	if (point_offset > d.size())
		fail(path, 96,
		     "offset to point data (" + std::to_string(point_offset) +
		         ") lies beyond the end of the file (" +
		         std::to_string(d.size()) + " bytes)");
	// Compared in records, so that a huge (corrupt) count cannot overflow.
	const uint64_t avail = (d.size() - point_offset) / record_len;
	std::string damage;
	if (n > avail && partial)
	{
		damage = path + ": byte " +
		         std::to_string(point_offset + avail * record_len) +
		         ": truncated: " + std::to_string(avail) + " of " +
		         std::to_string(n) + " point records are complete";
		n = avail;
	}
	else if (n > avail)
		fail(path, d.size(),
		     "point count " + std::to_string(n) +
		         " exceeds the file: " + std::to_string(n) + " records of " +
		         std::to_string(record_len) + " bytes from byte " +
		         std::to_string(point_offset) + " need more than the " +
		         std::to_string(d.size()) + " bytes the file has");
	double scale[3], offset[3];
	for (int i = 0; i < 3; i++)
	{
		scale[i] = get<double>(d, 131 + 8 * i);
		offset[i] = get<double>(d, 155 + 8 * i);
		if (!(std::isfinite(scale[i]) && scale[i] != 0 &&
		      std::isfinite(offset[i])))
			fail(path, 131 + 8 * i, "invalid scale/offset");
	}
	const bool has_gps = format == 1 || format == 3 || format >= 6;
	const size_t gps_at = format >= 6 ? 22 : 20;
	PointCloudFile out;
	out.damage = damage;
	out.xyz.resize(n);
	out.intensity.resize(n);
	out.classification.resize(n);
	if (has_gps) out.gps_time_s.resize(n);
	out.scan_angle_deg.resize(n);
	for (uint64_t k = 0; k < n; k++)
	{
		const size_t r = point_offset + k * record_len;
		out.xyz[k] = {get<int32_t>(d, r) * scale[0] + offset[0],
		              get<int32_t>(d, r + 4) * scale[1] + offset[1],
		              get<int32_t>(d, r + 8) * scale[2] + offset[2]};
		out.intensity[k] = get<uint16_t>(d, r + 12);
		// Formats 0–5 pack flags in the upper 3 bits of the class byte.
		out.classification[k] = format >= 6
		                            ? static_cast<uint8_t>(d[r + 16])
		                            : static_cast<uint8_t>(d[r + 15] & 0x1F);
		if (has_gps) out.gps_time_s[k] = get<double>(d, r + gps_at);
		out.scan_angle_deg[k] =
		    format >= 6 ? get<int16_t>(d, r + 18) * 0.006f
		                : static_cast<float>(static_cast<int8_t>(d[r + 16]));
	}
	return out;
}

PointCloudFile readPly(const std::string& path)
{
	const auto d = slurp(path);
	if (d.size() < 4 || std::memcmp(d.data(), "ply", 3) != 0)
		fail(path, 0, "bad signature (expected 'ply')");
	std::vector<std::string> lines;
	const size_t start = headerEnd(d, path, "end_header", lines);
	bool binary = false, in_vertex = false, seen_element = false;
	size_t n = 0, rec = 0, col = 0;
	std::vector<Field> fields;
	for (const auto& line : lines)
	{
		std::istringstream is(line);
		std::string key;
		is >> key;
		if (key == "format")
		{
			std::string f;
			is >> f;
			if (f == "binary_little_endian")
				binary = true;
			else if (f != "ascii")
				throw CloudFileError(
				    path + ": PLY format '" + f +
				    "' not supported (ascii, binary_little_endian)");
		}
		else if (key == "element")
		{
			std::string name;
			size_t count = 0;
			is >> name >> count;
			if (!seen_element && name != "vertex")
				throw CloudFileError(
				    path + ": the first PLY element must be 'vertex', got '" +
				    name + "'");
			in_vertex = !seen_element;
			if (in_vertex) n = count;
			seen_element = true;
		}
		else if (key == "property" && in_vertex)
		{
			std::string type, name;
			is >> type >> name;
			Field f;
			if (type == "list" || !plyScalar(type, f.type))
				throw CloudFileError(path + ": vertex property '" + name +
				                     "' has unsupported type '" + type + "'");
			f.name = name;
			f.offset = rec;
			f.column = col++;
			rec += scalarSize(f.type);
			fields.push_back(f);
		}
	}
	requireXyz(fields, path);
	PointCloudFile out;
	readRecords(d, start, n, fields, rec, binary, false, path, out);
	return out;
}

PointCloudFile readPcd(const std::string& path)
{
	const auto d = slurp(path);
	std::vector<std::string> lines;
	const size_t start = headerEnd(d, path, "data", lines);
	std::vector<std::string> names, sizes, types, counts;
	size_t n = 0;
	bool binary = false, have_points = false;
	for (const auto& line : lines)
	{
		std::istringstream is(line);
		std::string key, v;
		is >> key;
		std::vector<std::string> vals;
		while (is >> v) vals.push_back(v);
		if (key == "FIELDS")
			names = vals;
		else if (key == "SIZE")
			sizes = vals;
		else if (key == "TYPE")
			types = vals;
		else if (key == "COUNT")
			counts = vals;
		else if (key == "POINTS" && !vals.empty())
		{
			n = std::stoull(vals[0]);
			have_points = true;
		}
		else if (key == "DATA" && !vals.empty())
		{
			if (vals[0] == "binary")
				binary = true;
			else if (vals[0] != "ascii")
				throw CloudFileError(path + ": PCD DATA '" + vals[0] +
				                     "' not supported (ascii, binary)");
		}
	}
	if (names.empty() || sizes.size() != names.size() ||
	    types.size() != names.size() ||
	    (!counts.empty() && counts.size() != names.size()) || !have_points)
		throw CloudFileError(
		    path +
		    ": PCD header needs FIELDS, SIZE, TYPE (same length) and POINTS");
	std::vector<Field> fields;
	size_t rec = 0, col = 0;
	for (size_t i = 0; i < names.size(); i++)
	{
		Field f;
		f.name = names[i];
		f.count = counts.empty() ? 1 : std::stoul(counts[i]);
		const int sz = std::stoi(sizes[i]);
		const char t = types[i].empty() ? '?' : types[i][0];
		if (t == 'F' && sz == 4)
			f.type = Scalar::F32;
		else if (t == 'F' && sz == 8)
			f.type = Scalar::F64;
		else if (t == 'U' || t == 'I')
		{
			const bool u = t == 'U';
			if (sz == 1)
				f.type = u ? Scalar::U8 : Scalar::I8;
			else if (sz == 2)
				f.type = u ? Scalar::U16 : Scalar::I16;
			else if (sz == 4)
				f.type = u ? Scalar::U32 : Scalar::I32;
			else if (sz == 8)
				f.type = u ? Scalar::U64 : Scalar::I64;
			else
				throw CloudFileError(path + ": field '" + f.name +
				                     "' has bad SIZE");
		}
		else
			throw CloudFileError(path + ": field '" + f.name +
			                     "' has unsupported TYPE/SIZE");
		f.offset = rec;
		f.column = col;
		rec += scalarSize(f.type) * f.count;
		col += f.count;
		fields.push_back(f);
	}
	requireXyz(fields, path);
	PointCloudFile out;
	readRecords(d, start, n, fields, rec, binary, true, path, out);
	return out;
}

PointCloudFile readCloudFile(const std::string& path, bool partial)
{
	const auto dot = path.find_last_of('.');
	const std::string ext =
	    dot == std::string::npos ? "" : lower(path.substr(dot + 1));
	if (ext == "las") return readLas(path, partial);
	if (ext == "ply") return readPly(path);
	if (ext == "pcd") return readPcd(path);
	if (ext == "laz")
		throw CloudFileError(
		    path + ": LAZ is not supported; decompress with laszip first");
	throw CloudFileError(
	    path + ": unknown cloud file extension (expected .las, .ply, .pcd)");
}

}  // namespace forest_slam::io
