// LAS 1.4 writer, point data record format 6. Byte layout from the ASPRS LAS
// 1.4 R15 specification: public header block (table 3, 375 bytes), variable
// length record header (table 4, 54 bytes), OGC WKT record (2112), point
// record format 6 (table 13, 30 bytes).
#include <forest_slam/core/atomic_file.h>
#include <forest_slam/io/las.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <ctime>
#include <limits>

namespace forest_slam::io
{
namespace
{
constexpr uint16_t kHeaderSize = 375;
constexpr uint16_t kVlrHeaderSize = 54;
constexpr uint16_t kRecordLength = 30;

class Bytes
{
   public:
	explicit Bytes(size_t n) : b_(n, 0) {}
	template <typename T>
	void put(size_t off, T v)
	{
		std::memcpy(b_.data() + off, &v, sizeof(T));  // little-endian hosts
	}
	void text(size_t off, size_t width, const std::string& s)
	{
		std::memcpy(b_.data() + off, s.data(), std::min(width, s.size()));
	}
	const char* data() const { return b_.data(); }
	size_t size() const { return b_.size(); }

   private:
	std::vector<char> b_;
};
}  // namespace

double unixToAdjustedGpsTime(double unix_s)
{
	// GPS epoch 1980-01-06 = UNIX 315964800; GPS is ahead of UTC by the leap
	// seconds since then (18 from 2017-01-01).
	return unix_s - 315964800.0 + 18.0 - 1e9;
}

void writeLas(const std::string& path, const PointCloudFile& c,
              const LasWriteOptions& o)
{
	const size_t n = c.size();
	const auto check = [&](size_t m, const char* what)
	{
		if (m != 0 && m != n)
			throw CloudFileError(path + ": " + what + " has " +
			                     std::to_string(m) + " entries for " +
			                     std::to_string(n) + " points");
	};
	check(c.intensity.size(), "intensity");
	check(c.classification.size(), "classification");
	check(c.gps_time_s.size(), "gps_time_s");
	check(c.scan_angle_deg.size(), "scan_angle_deg");
	if (!(o.scale_m > 0)) throw CloudFileError(path + ": scale must be > 0");

	// Offsets: the minimum rounded down to a metre, so coordinates stay
	// readable and the integers small.
	Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = lo, offset = lo;
	if (n > 0)
	{
		lo = hi = c.xyz[0];
		for (const auto& p : c.xyz)
		{
			if (!p.allFinite())
				throw CloudFileError(path + ": non-finite coordinate");
			lo = lo.cwiseMin(p);
			hi = hi.cwiseMax(p);
		}
		offset = lo.array().floor();
		const double span = (hi - offset).maxCoeff() / o.scale_m;
		if (span > std::numeric_limits<int32_t>::max())
			throw CloudFileError(
			    path + ": the cloud spans " +
			    std::to_string((hi - lo).maxCoeff()) +
			    " m, too much for 32-bit coordinates at scale " +
			    std::to_string(o.scale_m) + " m");
	}
	const auto quantize = [&](const Eigen::Vector3d& p, int i) {
		return static_cast<int32_t>(
		    std::llround((p[i] - offset[i]) / o.scale_m));
	};
	// Header bounds are those of the stored (quantized) coordinates.
	Eigen::Vector3d qlo = Eigen::Vector3d::Zero(), qhi = qlo;
	for (size_t k = 0; k < n; k++)
		for (int i = 0; i < 3; i++)
		{
			const double v = quantize(c.xyz[k], i) * o.scale_m + offset[i];
			if (k == 0 || v < qlo[i]) qlo[i] = v;
			if (k == 0 || v > qhi[i]) qhi[i] = v;
		}

	const bool wkt = !o.wkt.empty();
	const size_t wkt_len = o.wkt.size() + 1;  // null-terminated
	if (wkt_len > std::numeric_limits<uint16_t>::max())
		throw CloudFileError(path + ": WKT longer than a VLR can hold");
	const uint32_t point_offset =
	    kHeaderSize +
	    (wkt ? kVlrHeaderSize + static_cast<uint32_t>(wkt_len) : 0);

	Bytes h(kHeaderSize);
	h.text(0, 4, "LASF");
	// Global encoding: bit 0 adjusted standard GPS time; bit 4 the CRS is
	// WKT (required for point formats >= 6).
	h.put<uint16_t>(6, static_cast<uint16_t>(
	                       (o.adjusted_standard_gps_time ? 1 : 0) | (1 << 4)));
	h.put<uint8_t>(24, 1);
	h.put<uint8_t>(25, 4);
	h.text(26, 32, o.system_id);
	h.text(58, 32, o.software);
	const std::time_t now = std::time(nullptr);
	std::tm utc{};
	gmtime_r(&now, &utc);
	h.put<uint16_t>(90, static_cast<uint16_t>(utc.tm_yday + 1));
	h.put<uint16_t>(92, static_cast<uint16_t>(utc.tm_year + 1900));
	h.put<uint16_t>(94, kHeaderSize);
	h.put<uint32_t>(96, point_offset);
	h.put<uint32_t>(100, wkt ? 1 : 0);  // number of VLRs
	h.put<uint8_t>(104, 6);
	h.put<uint16_t>(105, kRecordLength);
	// 107: legacy point count, 111: legacy counts by return: 0 (format 6).
	for (int i = 0; i < 3; i++)
	{
		h.put<double>(131 + 8 * i, o.scale_m);
		h.put<double>(155 + 8 * i, offset[i]);
		h.put<double>(179 + 16 * i, qhi[i]);  // max x, max y, max z
		h.put<double>(187 + 16 * i, qlo[i]);  // min ...
	}
	// 227 waveform start, 235 first EVLR, 243 EVLR count: none.
	h.put<uint64_t>(247, n);
	h.put<uint64_t>(255, n);  // every point is return 1 of 1
	// 263..375: points of returns 2..15: 0.

	core::AtomicFileWriter file(path, true);
	auto& os = file.stream();
	os.write(h.data(), static_cast<std::streamsize>(h.size()));
	if (wkt)
	{
		Bytes v(kVlrHeaderSize);
		v.text(2, 16, "LASF_Projection");
		v.put<uint16_t>(18, 2112);
		v.put<uint16_t>(20, static_cast<uint16_t>(wkt_len));
		v.text(22, 32, "OGC coordinate system WKT");
		os.write(v.data(), static_cast<std::streamsize>(v.size()));
		os.write(o.wkt.c_str(), static_cast<std::streamsize>(wkt_len));
	}
	constexpr size_t kChunk = 8192;
	Bytes rec(kChunk * kRecordLength);
	for (size_t k0 = 0; k0 < n; k0 += kChunk)
	{
		const size_t m = std::min(kChunk, n - k0);
		for (size_t j = 0; j < m; j++)
		{
			const size_t k = k0 + j, r = j * kRecordLength;
			rec.put<int32_t>(r, quantize(c.xyz[k], 0));
			rec.put<int32_t>(r + 4, quantize(c.xyz[k], 1));
			rec.put<int32_t>(r + 8, quantize(c.xyz[k], 2));
			rec.put<uint16_t>(r + 12, c.intensity.empty() ? 0 : c.intensity[k]);
			rec.put<uint8_t>(r + 14, 0x11);  // return 1 of 1
			rec.put<uint8_t>(r + 15, 0);     // flags, channel, direction, edge
			rec.put<uint8_t>(
			    r + 16, c.classification.empty() ? 1 : c.classification[k]);
			rec.put<uint8_t>(r + 17, 0);  // user data
			const double a =
			    c.scan_angle_deg.empty() ? 0.0 : c.scan_angle_deg[k];
			rec.put<int16_t>(
			    r + 18, static_cast<int16_t>(std::clamp(std::lround(a / 0.006),
			                                            -30000L, 30000L)));
			rec.put<uint16_t>(r + 20, 0);  // point source id
			rec.put<double>(r + 22,
			                c.gps_time_s.empty() ? 0.0 : c.gps_time_s[k]);
		}
		os.write(rec.data(), static_cast<std::streamsize>(m * kRecordLength));
	}
	file.commit();
}

}  // namespace forest_slam::io
