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

struct LasStreamWriter::Impl
{
	std::string path;
	uint64_t promised = 0, written = 0;
	Eigen::Vector3d offset, qlo, qhi;
	LasWriteOptions o;
	core::AtomicFileWriter file;
	Bytes header{kHeaderSize};
	static constexpr size_t kChunk = 8192;
	Bytes rec{kChunk * kRecordLength};
	size_t in_chunk = 0;

	Impl(const std::string& p, uint64_t n, const Eigen::Vector3d& off,
	     const LasWriteOptions& opt)
	    : path(p), promised(n), offset(off), o(opt), file(p, true)
	{
	}
	int32_t quantize(double v, int i) const
	{
		const double q = std::llround((v - offset[i]) / o.scale_m);
		if (!(q >= std::numeric_limits<int32_t>::min() &&
		      q <= std::numeric_limits<int32_t>::max()))
			throw CloudFileError(
			    path +
			    ": a coordinate lies too far from the offset for "
			    "32-bit coordinates at scale " +
			    std::to_string(o.scale_m) + " m");
		return static_cast<int32_t>(q);
	}
	void flush()
	{
		file.stream().write(
		    rec.data(), static_cast<std::streamsize>(in_chunk * kRecordLength));
		in_chunk = 0;
	}
	void fillHeader()
	{
		Bytes& h = header;
		h.text(0, 4, "LASF");
		// Global encoding: bit 0 adjusted standard GPS time; bit 4 the CRS
		// is WKT (required for point formats >= 6).
		h.put<uint16_t>(
		    6, static_cast<uint16_t>((o.adjusted_standard_gps_time ? 1 : 0) |
		                             (1 << 4)));
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
		const bool wkt = !o.wkt.empty();
		const uint32_t point_offset =
		    kHeaderSize +
		    (wkt ? kVlrHeaderSize + static_cast<uint32_t>(o.wkt.size() + 1)
		         : 0);
		h.put<uint32_t>(96, point_offset);
		h.put<uint32_t>(100, wkt ? 1 : 0);  // number of VLRs
		h.put<uint8_t>(104, 6);
		h.put<uint16_t>(105, kRecordLength);
		// 107: legacy point count, 111: legacy counts by return: 0 (format
		// 6).
		for (int i = 0; i < 3; i++)
		{
			h.put<double>(131 + 8 * i, o.scale_m);
			h.put<double>(155 + 8 * i, offset[i]);
			h.put<double>(179 + 16 * i, written ? qhi[i] : 0.0);  // max
			h.put<double>(187 + 16 * i, written ? qlo[i] : 0.0);  // min
		}
		// 227 waveform start, 235 first EVLR, 243 EVLR count: none.
		h.put<uint64_t>(247, promised);
		h.put<uint64_t>(255, promised);  // every point is return 1 of 1
		// 263..375: points of returns 2..15: 0.
	}
};

LasStreamWriter::LasStreamWriter(const std::string& path, uint64_t points,
                                 const Eigen::Vector3d& offset,
                                 const LasWriteOptions& o)
{
	if (!(o.scale_m > 0)) throw CloudFileError(path + ": scale must be > 0");
	if (!offset.allFinite())
		throw CloudFileError(path + ": non-finite coordinate offset");
	const size_t wkt_len = o.wkt.size() + 1;  // null-terminated
	if (!o.wkt.empty() && wkt_len > std::numeric_limits<uint16_t>::max())
		throw CloudFileError(path + ": WKT longer than a VLR can hold");
	impl_ = new Impl(path, points, offset, o);
	impl_->fillHeader();  // bounds rewritten by commit()
	auto& os = impl_->file.stream();
	os.write(impl_->header.data(),
	         static_cast<std::streamsize>(impl_->header.size()));
	if (!o.wkt.empty())
	{
		Bytes v(kVlrHeaderSize);
		v.text(2, 16, "LASF_Projection");
		v.put<uint16_t>(18, 2112);
		v.put<uint16_t>(20, static_cast<uint16_t>(wkt_len));
		v.text(22, 32, "OGC coordinate system WKT");
		os.write(v.data(), static_cast<std::streamsize>(v.size()));
		os.write(o.wkt.c_str(), static_cast<std::streamsize>(wkt_len));
	}
}

LasStreamWriter::~LasStreamWriter()
{
	delete impl_;
}

void LasStreamWriter::add(const Eigen::Vector3d& p, uint16_t intensity,
                          uint8_t classification, float scan_angle_deg,
                          double gps_time_s)
{
	Impl& m = *impl_;
	if (!p.allFinite())
		throw CloudFileError(m.path + ": non-finite coordinate");
	if (m.written == m.promised)
		throw CloudFileError(m.path + ": more points than the " +
		                     std::to_string(m.promised) + " announced");
	const size_t r = m.in_chunk * kRecordLength;
	for (int i = 0; i < 3; i++)
	{
		const int32_t q = m.quantize(p[i], i);
		m.rec.put<int32_t>(r + 4 * i, q);
		// Header bounds are those of the stored (quantized) coordinates.
		const double v = q * m.o.scale_m + m.offset[i];
		if (m.written == 0 || v < m.qlo[i]) m.qlo[i] = v;
		if (m.written == 0 || v > m.qhi[i]) m.qhi[i] = v;
	}
	m.rec.put<uint16_t>(r + 12, intensity);
	m.rec.put<uint8_t>(r + 14, 0x11);  // return 1 of 1
	m.rec.put<uint8_t>(r + 15, 0);     // flags, channel, direction, edge
	m.rec.put<uint8_t>(r + 16, classification);
	m.rec.put<uint8_t>(r + 17, 0);  // user data
	m.rec.put<int16_t>(
	    r + 18, static_cast<int16_t>(std::clamp(
	                std::lround(scan_angle_deg / 0.006), -30000L, 30000L)));
	m.rec.put<uint16_t>(r + 20, 0);  // point source id
	m.rec.put<double>(r + 22, gps_time_s);
	m.written++;
	if (++m.in_chunk == Impl::kChunk) m.flush();
}

void LasStreamWriter::commit()
{
	Impl& m = *impl_;
	if (m.written != m.promised)
		throw CloudFileError(m.path + ": " + std::to_string(m.written) +
		                     " points written, " + std::to_string(m.promised) +
		                     " announced");
	m.flush();
	m.fillHeader();
	auto& os = m.file.stream();
	os.seekp(0);
	os.write(m.header.data(), static_cast<std::streamsize>(m.header.size()));
	os.seekp(0, std::ios::end);
	m.file.commit();
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
	Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = lo;
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
		const double span =
		    (hi - LasStreamWriter::offsetFor(lo)).maxCoeff() / o.scale_m;
		if (span > std::numeric_limits<int32_t>::max())
			throw CloudFileError(
			    path + ": the cloud spans " +
			    std::to_string((hi - lo).maxCoeff()) +
			    " m, too much for 32-bit coordinates at scale " +
			    std::to_string(o.scale_m) + " m");
	}
	LasStreamWriter w(path, n, n > 0 ? LasStreamWriter::offsetFor(lo) : lo, o);
	for (size_t k = 0; k < n; k++)
		w.add(c.xyz[k], c.intensity.empty() ? 0 : c.intensity[k],
		      c.classification.empty() ? 1 : c.classification[k],
		      c.scan_angle_deg.empty() ? 0.0f : c.scan_angle_deg[k],
		      c.gps_time_s.empty() ? 0.0 : c.gps_time_s[k]);
	w.commit();
}

}  // namespace forest_slam::io
