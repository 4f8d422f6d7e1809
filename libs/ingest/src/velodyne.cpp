#include <forest_slam/core/lidar_model.h>
#include <forest_slam/ingest/stamps.h>
#include <forest_slam/ingest/velodyne.h>

#include <mrpt/system/datetime.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <stdexcept>

namespace forest_slam::ingest
{
namespace
{
constexpr double kDeg = M_PI / 180.0;
constexpr int kBlocks = 12;
constexpr int kReturnsPerBlock = 32;
constexpr uint16_t kUpperBank = 0xEEFF;
constexpr uint8_t kRetDual = 0x39;
constexpr double kUsPerHour = 3600e6;

static_assert(sizeof(mrpt::obs::CObservationVelodyneScan::TVelodyneRawPacket) ==
                  kVelodynePacketBytes,
              "MRPT's raw packet struct must be the 1206-byte UDP payload");

uint16_t le16(const uint8_t* p)
{
	return static_cast<uint16_t>(p[0] | (p[1] << 8));
}
uint32_t le32(const uint8_t* p)
{
	return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
	       (static_cast<uint32_t>(p[2]) << 16) |
	       (static_cast<uint32_t>(p[3]) << 24);
}

std::string trim(const std::string& s)
{
	const auto b = s.find_first_not_of(" \t\r\n\"'");
	if (b == std::string::npos) return "";
	const auto e = s.find_last_not_of(" \t\r\n\"'");
	return s.substr(b, e - b + 1);
}

double toDouble(const std::string& v, const std::string& where)
{
	try
	{
		size_t used = 0;
		const double d = std::stod(v, &used);
		if (used != v.size()) throw std::invalid_argument(v);
		return d;
	}
	catch (const std::exception&)
	{
		throw std::runtime_error(where + ": expected a number, got '" + v +
		                         "'");
	}
}

VelodyneCalib parseRosYaml(const std::string& text, const std::string& path)
{
	VelodyneCalib c;
	c.source = path;
	const auto lasers_at = text.find("lasers:");
	if (lasers_at == std::string::npos)
		throw std::runtime_error("calibration '" + path +
		                         "' has no 'lasers:' list");
	// Top-level scalars (no indentation) anywhere in the file.
	std::istringstream lines(text);
	std::string line;
	size_t expected = 0;
	while (std::getline(lines, line))
	{
		if (line.empty() || std::isspace(static_cast<unsigned char>(line[0])) ||
		    line[0] == '-')
			continue;
		const auto colon = line.find(':');
		if (colon == std::string::npos) continue;
		const std::string key = trim(line.substr(0, colon));
		const std::string val = trim(line.substr(colon + 1));
		if (key == "distance_resolution")
			c.distance_resolution_m =
			    toDouble(val, path + ": distance_resolution");
		else if (key == "num_lasers")
			expected =
			    static_cast<size_t>(toDouble(val, path + ": num_lasers"));
	}
	// The list runs from "lasers:" to the next unindented key.
	size_t end = text.size();
	{
		std::regex top_key("\n[A-Za-z_][A-Za-z0-9_]*\\s*:");
		std::smatch m;
		const std::string rest = text.substr(lasers_at + 7);
		if (std::regex_search(rest, m, top_key))
			end = lasers_at + 7 + m.position(0);
	}
	std::string list = text.substr(lasers_at + 7, end - lasers_at - 7);
	// Items start with "-" (block or flow style); inside an item, braces
	// and commas separate "key: value" pairs.
	std::vector<std::string> items;
	{
		std::regex dash("(^|\n)[ \t]*-[ \t]");
		std::sregex_token_iterator it(list.begin(), list.end(), dash, -1), e;
		for (; it != e; ++it)
			if (!trim(*it).empty()) items.push_back(*it);
	}
	std::map<int, VelodyneLaserCalib> by_id;
	int item_no = 0;
	for (auto item : items)
	{
		for (char& ch : item)
			if (ch == '{' || ch == '}' || ch == ',') ch = '\n';
		std::map<std::string, double> kv;
		std::istringstream is(item);
		const std::string where =
		    path + ": laser item #" + std::to_string(item_no);
		while (std::getline(is, line))
		{
			const auto colon = line.find(':');
			if (colon == std::string::npos)
			{
				if (!trim(line).empty())
					throw std::runtime_error(where + ": cannot parse '" +
					                         trim(line) + "'");
				continue;
			}
			kv[trim(line.substr(0, colon))] =
			    toDouble(trim(line.substr(colon + 1)),
			             where + " " + trim(line.substr(0, colon)));
		}
		if (!kv.count("laser_id") || !kv.count("vert_correction"))
			throw std::runtime_error(where +
			                         ": needs laser_id and vert_correction");
		VelodyneLaserCalib l;
		l.vert_rad = kv["vert_correction"];
		l.rot_rad = kv.count("rot_correction") ? kv["rot_correction"] : 0;
		l.dist_m = kv.count("dist_correction") ? kv["dist_correction"] : 0;
		l.vert_offset_m = kv.count("vert_offset_correction")
		                      ? kv["vert_offset_correction"]
		                      : 0;
		l.horiz_offset_m = kv.count("horiz_offset_correction")
		                       ? kv["horiz_offset_correction"]
		                       : 0;
		const int id = static_cast<int>(kv["laser_id"]);
		if (id < 0 || by_id.count(id))
			throw std::runtime_error(where + ": bad or repeated laser_id " +
			                         std::to_string(id));
		by_id[id] = l;
		item_no++;
	}
	for (int i = 0; i < static_cast<int>(by_id.size()); i++)
	{
		if (!by_id.count(i))
			throw std::runtime_error("calibration '" + path +
			                         "': laser ids are not 0.." +
			                         std::to_string(by_id.size() - 1) +
			                         " (missing " + std::to_string(i) + ")");
		c.lasers.push_back(by_id[i]);
	}
	if (c.lasers.empty())
		throw std::runtime_error("calibration '" + path + "' lists no lasers");
	if (expected && expected != c.lasers.size())
		throw std::runtime_error("calibration '" + path + "' says num_lasers " +
		                         std::to_string(expected) + " but lists " +
		                         std::to_string(c.lasers.size()));
	return c;
}

}  // namespace

VelodyneCalib loadVelodyneCalibration(const std::string& path)
{
	std::ifstream f(path);
	if (!f)
		throw std::runtime_error("cannot open Velodyne calibration '" + path +
		                         "'");
	std::stringstream ss;
	ss << f.rdbuf();
	const std::string text = ss.str();
	if (text.find("<boost_serialization") != std::string::npos ||
	    text.find("<DB>") != std::string::npos)
	{
		mrpt::obs::VelodyneCalibration m;
		if (!m.loadFromXMLFile(path) || m.empty())
			throw std::runtime_error("cannot parse Velodyne XML calibration '" +
			                         path + "'");
		auto c = fromMrpt(m);
		c.source = path;
		return c;
	}
	return parseRosYaml(text, path);
}

VelodyneCalib defaultVelodyneCalibration(const std::string& model)
{
	const auto* m = core::findLidarModel(model);
	const std::string name = m ? m->name : model;
	if (name != "VLP16" && name != "HDL32")
		throw std::invalid_argument(
		    "MRPT has no default calibration for Velodyne model '" + model +
		    "': give calibration_file (the ROS driver's YAML or the sensor's "
		    "XML)");
	auto c =
	    fromMrpt(mrpt::obs::VelodyneCalibration::LoadDefaultCalibration(name));
	if (c.lasers.empty())
		throw std::runtime_error("MRPT's default calibration for " + name +
		                         " is empty");
	c.source = "MRPT default " + name;
	return c;
}

mrpt::obs::VelodyneCalibration toMrpt(const VelodyneCalib& c)
{
	// MRPT keeps angles in degrees and distances in meters.
	mrpt::obs::VelodyneCalibration m;
	for (const auto& l : c.lasers)
	{
		mrpt::obs::VelodyneCalibration::PerLaserCalib p;
		p.azimuthCorrection = l.rot_rad / kDeg;
		p.verticalCorrection = l.vert_rad / kDeg;
		p.distanceCorrection = l.dist_m;
		p.verticalOffsetCorrection = l.vert_offset_m;
		p.horizontalOffsetCorrection = l.horiz_offset_m;
		p.sinVertCorrection = std::sin(l.vert_rad);
		p.cosVertCorrection = std::cos(l.vert_rad);
		p.sinVertOffsetCorrection = p.sinVertCorrection * l.vert_offset_m;
		p.cosVertOffsetCorrection = p.cosVertCorrection * l.vert_offset_m;
		m.laser_corrections.push_back(p);
	}
	return m;
}

VelodyneCalib fromMrpt(const mrpt::obs::VelodyneCalibration& m)
{
	VelodyneCalib c;
	for (const auto& p : m.laser_corrections)
	{
		VelodyneLaserCalib l;
		l.vert_rad = p.verticalCorrection * kDeg;
		l.rot_rad = p.azimuthCorrection * kDeg;
		l.dist_m = p.distanceCorrection;
		l.vert_offset_m = p.verticalOffsetCorrection;
		l.horiz_offset_m = p.horizontalOffsetCorrection;
		c.lasers.push_back(l);
	}
	c.source = "MRPT observation";
	return c;
}

std::string lidarModelForVelodyneId(uint8_t id)
{
	switch (id)
	{
		case kVlp16:
		case kVlp16HiRes:
			return "VLP16";
		case kHdl32e:
			return "HDL32";
		case kVlp32c:
			return "VLP32C";
		default:
			return "";
	}
}

uint8_t resolveVelodyneModel(uint8_t model_byte, size_t calibration_lasers)
{
	if (!lidarModelForVelodyneId(model_byte).empty()) return model_byte;
	if (calibration_lasers == 16) return kVlp16;
	if (calibration_lasers == 32) return kHdl32e;
	return 0;
}

DualReturn parseDualReturn(const std::string& s)
{
	if (s == "strongest") return DualReturn::Strongest;
	if (s == "last") return DualReturn::Last;
	if (s == "both") return DualReturn::Both;
	throw std::invalid_argument("dual return '" + s +
	                            "' is not one of strongest, last, both");
}

void decodeVelodynePackets(const std::vector<const uint8_t*>& packets,
                           const VelodyneCalib& calib,
                           const VelodyneDecodeOptions& opts,
                           std::vector<VelodynePoint>& out)
{
	out.clear();
	if (packets.empty()) return;
	const uint8_t model_byte = packets[0][1205];
	const uint8_t model = resolveVelodyneModel(model_byte, calib.lasers.size());
	const std::string model_name = lidarModelForVelodyneId(model);
	if (model_name.empty())
		throw std::runtime_error(
		    "Velodyne packet 0 has model byte 0x" +
		    [&]
		    {
			    std::ostringstream o;
			    o << std::hex << int(model_byte);
			    return o.str();
		    }() +
		    ": only VLP-16 (0x22/0x24), HDL-32E (0x21) and "
		    "VLP-32C (0x28) are supported");
	const bool vlp16 = model == kVlp16 || model == kVlp16HiRes;
	const size_t n_lasers = vlp16 ? 16 : 32;
	if (calib.lasers.size() != n_lasers)
		throw std::runtime_error("calibration '" + calib.source + "' has " +
		                         std::to_string(calib.lasers.size()) +
		                         " lasers but the " + model_name +
		                         " packets need " + std::to_string(n_lasers));
	const double res = calib.distance_resolution_m > 0
	                       ? calib.distance_resolution_m
	                   : model == kVlp32c ? 0.004
	                                      : 0.002;
	std::vector<double> cos_v(n_lasers), sin_v(n_lasers);
	for (size_t i = 0; i < n_lasers; i++)
	{
		cos_v[i] = std::cos(calib.lasers[i].vert_rad);
		sin_v[i] = std::sin(calib.lasers[i].vert_rad);
	}
	out.reserve(packets.size() * kBlocks * kReturnsPerBlock);

	double t_pkt_us = 0;
	uint32_t prev_us = le32(packets[0] + 1200);
	for (size_t pi = 0; pi < packets.size(); pi++)
	{
		const uint8_t* pkt = packets[pi];
		if (pkt[1205] != model_byte)
			throw std::runtime_error("Velodyne packet " + std::to_string(pi) +
			                         " has another model byte than packet 0");
		const uint32_t us = le32(pkt + 1200);
		t_pkt_us += std::fmod(static_cast<double>(us) - prev_us + kUsPerHour,
		                      kUsPerHour);
		prev_us = us;
		const bool dual = pkt[1204] == kRetDual;
		const int per_az = dual ? 2 : 1;  // blocks sharing one azimuth
		float last_diff = 0;
		for (int b = 0; b < kBlocks; b++)
		{
			const uint8_t* blk = pkt + b * 100;
			if (le16(blk) != kUpperBank)
				continue;  // HDL-64 lower bank, garbage
			if (dual)
			{
				const bool strongest_block = (b & 1) != 0;
				if (opts.dual == DualReturn::Strongest && !strongest_block)
					continue;
				if (opts.dual == DualReturn::Last && strongest_block) continue;
			}
			const uint16_t az = le16(blk + 2);
			float az_diff = last_diff;
			if (b + per_az < kBlocks)
			{
				az_diff = static_cast<float>(
				    (36000 + le16(pkt + (b + per_az) * 100 + 2) - az) % 36000);
				last_diff = az_diff;
			}
			const int firing_block = dual ? b / 2 : b;
			for (int k = 0; k < kReturnsPerBlock; k++)
			{
				const uint8_t* ret = blk + 4 + 3 * k;
				const uint16_t raw = le16(ret);
				if (raw == 0) continue;
				if (dual && opts.dual == DualReturn::Both && (b & 1))
				{
					// The second block repeats the first when both echoes
					// coincide.
					const uint8_t* other = pkt + (b - 1) * 100 + 4 + 3 * k;
					if (le16(other) == raw) continue;
				}
				const int laser = vlp16 ? k % 16 : k;
				const auto& cal = calib.lasers[laser];
				double d = raw * res;
				if (d > 1e-6) d += cal.dist_m;
				if (!(d > opts.min_range_m && d < opts.max_range_m)) continue;
				// Firing time within the block's firing cycle, then the
				// azimuth reached at that time.
				double off_us, cycle_us;
				if (vlp16)
				{
					off_us = (k / 16) * 55.296 + (k % 16) * 2.304;
					cycle_us = 110.592;
				}
				else if (model == kVlp32c)
				{
					off_us = (k / 2) * 2.304;  // lasers fire in pairs
					cycle_us = 55.296;
				}
				else
				{
					off_us = k * 1.152;
					cycle_us = 46.08;
				}
				const double t_us = t_pkt_us + firing_block * cycle_us + off_us;
				const uint16_t az_c = static_cast<uint16_t>(
				    static_cast<int>(
				        std::round(az + az_diff * off_us / cycle_us)) %
				    36000);
				const double a = az_c * 0.01 * kDeg - cal.rot_rad;
				const double xy =
				    d * cos_v[laser] - cal.vert_offset_m * sin_v[laser];
				VelodynePoint p;
				p.x = static_cast<float>(xy * std::cos(a) +
				                         cal.horiz_offset_m * std::sin(a));
				p.y = static_cast<float>(-xy * std::sin(a) +
				                         cal.horiz_offset_m * std::cos(a));
				p.z = static_cast<float>(d * sin_v[laser] +
				                         cal.vert_offset_m * cos_v[laser]);
				p.distance_m = static_cast<float>(d);
				p.intensity = ret[2];
				p.laser_id = static_cast<uint16_t>(laser);
				p.azimuth_cdeg = az_c;
				p.block = static_cast<uint8_t>(b);
				p.return_index = static_cast<uint8_t>(k);
				p.packet = static_cast<uint32_t>(pi);
				p.t_s = t_us * 1e-6;
				out.push_back(p);
			}
		}
	}
}

void decodeVelodyneScan(const mrpt::obs::CObservationVelodyneScan& scan,
                        const VelodyneDecodeOptions& opts,
                        std::vector<VelodynePoint>& out)
{
	out.clear();
	if (scan.scan_packets.empty()) return;
	std::vector<const uint8_t*> pkts;
	for (const auto& p : scan.scan_packets)
		pkts.push_back(reinterpret_cast<const uint8_t*>(&p));
	VelodyneCalib calib;
	if (!scan.calibration.empty())
		calib = fromMrpt(scan.calibration);
	else
		calib = defaultVelodyneCalibration(
		    lidarModelForVelodyneId(scan.scan_packets[0].velodyne_model_ID));
	decodeVelodynePackets(pkts, calib, opts, out);
}

void velodyneToRotatingScan(const mrpt::obs::CObservationVelodyneScan& in,
                            mrpt::obs::CObservationRotatingScan& out,
                            const VelodyneDecodeOptions& opts,
                            OrganizeStats* stats)
{
	if (in.scan_packets.empty())
		throw std::runtime_error("CObservationVelodyneScan has no packets");
	const uint8_t id =
	    resolveVelodyneModel(in.scan_packets[0].velodyne_model_ID,
	                         in.calibration.laser_corrections.size());
	std::vector<VelodynePoint> pts;
	decodeVelodyneScan(in, opts, pts);
	std::vector<CloudPoint> cloud(pts.size());
	for (size_t i = 0; i < pts.size(); i++)
	{
		auto& c = cloud[i];
		c.x = pts[i].x;
		c.y = pts[i].y;
		c.z = pts[i].z;
		c.intensity = pts[i].intensity;
		c.ring = pts[i].laser_id;
		c.t_s = pts[i].t_s;
	}
	OrganizerOptions oo;
	oo.lidar_model = lidarModelForVelodyneId(id);
	oo.ring_order = RingOrder::Native;
	oo.range_resolution_m = id == kVlp32c ? 0.004 : 0.002;
	oo.rotation_sign = -1;  // Velodynes spin clockwise seen from above
	ScanOrganizer org(oo);
	const mrpt::system::TTimeStamp ts = in.timestamp;
	org.organize(cloud, toUnixNs(ts), true, out, stats);
	out.sensorLabel = in.sensorLabel;
	out.sensorPose = in.sensorPose;
	out.originalReceivedTimestamp = in.originalReceivedTimestamp;
	out.has_satellite_timestamp = in.has_satellite_timestamp;
}

void velodyneScanFromMsg(const VelodyneScanMsg& msg, const VelodyneCalib& calib,
                         mrpt::obs::CObservationVelodyneScan& out)
{
	out.scan_packets.resize(msg.packets.size());
	for (size_t i = 0; i < msg.packets.size(); i++)
		std::memcpy(&out.scan_packets[i], msg.packets[i].data.data(),
		            kVelodynePacketBytes);
	out.calibration = toMrpt(calib);
	const int64_t t0 =
	    msg.packets.empty() ? msg.header.stamp_ns : msg.packets[0].stamp_ns;
	out.timestamp = fromUnixNs(t0);
	out.has_satellite_timestamp = false;
	out.point_cloud.clear();
	if (!msg.packets.empty())
		if (const auto* m = core::findLidarModel(
		        lidarModelForVelodyneId(resolveVelodyneModel(
		            msg.packets[0].data[1205], calib.lasers.size()))))
		{
			out.minRange = m->min_range_m;
			out.maxRange = m->max_range_m;
		}
}

}  // namespace forest_slam::ingest
