#pragma once
// Point cloud files from other tools (TLS scanners, other SLAM systems), read
// for the standalone tree mode (issue 7). LAS is read by our own reader since
// Debian ships no LAS library; LAZ (compressed) is rejected with a clear error.
#include <Eigen/Core>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace forest_slam::io
{
/** A cloud read from a file. Optional attributes are either empty or have one
 * entry per point. Coordinates are in the file's frame (LAS: scale and offset
 * applied), in double so that UTM coordinates keep millimetres. */
struct PointCloudFile
{
	std::vector<Eigen::Vector3d> xyz;
	std::vector<uint16_t> intensity;
	std::vector<uint8_t> classification;
	std::vector<double> gps_time_s;
	std::vector<float> scan_angle_deg;  ///< LAS: scan angle (rank)
	/** Read with `partial`: empty for a whole file, else what was cut off
	 * (file, byte offset, records read) — the points before it are kept. */
	std::string damage;

	size_t size() const { return xyz.size(); }
};

/** Any unreadable / invalid / truncated cloud file; the message names the
 * file and, for binary formats, the byte offset where reading failed. */
class CloudFileError : public std::runtime_error
{
   public:
	using std::runtime_error::runtime_error;
};

/** LAS 1.2–1.4, point data formats 0–3 and 6–8 (extra bytes per record are
 * skipped). Intensity and classification are always filled; GPS time for
 * formats 1, 3, 6, 7, 8. */
PointCloudFile readLas(const std::string& path, bool partial = false);

/** The LAS reader on bytes in memory (`name` labels errors); readLas and
 * the fuzz target (tests/fuzz) go through it. With `partial`, a point block
 * cut short yields the complete records before the cut and sets `damage`
 * instead of throwing. */
PointCloudFile parseLas(const std::vector<char>& bytes, const std::string& name,
                        bool partial = false);

struct LasWriteOptions
{
	double scale_m = 0.001;  ///< coordinate resolution (all three axes)
	/** OGC WKT of the coordinate system; empty: no CRS record. */
	std::string wkt;
	/** GPS time field holds adjusted standard GPS time (global encoding bit
	 * 0); the caller converts (see unixToAdjustedGpsTime). */
	bool adjusted_standard_gps_time = true;
	std::string system_id = "forest-slam lidar SLAM";
	std::string software = "forest-slam";
};

/** LAS 1.4, point data record format 6 (30 bytes: X Y Z, intensity, return 1
 * of 1, classification, scan angle in 0.006 deg, GPS time), written
 * atomically; with `wkt`, one OGC coordinate system WKT VLR (user
 * "LASF_Projection", record 2112). Empty optional attributes are written as
 * 0 (classification: 1, unclassified). The legacy point counts are 0 as the
 * specification requires for formats >= 6. Throws CloudFileError naming the
 * file if a coordinate does not fit 32 bits at the scale. */
void writeLas(const std::string& path, const PointCloudFile& cloud,
              const LasWriteOptions& o = LasWriteOptions());

/** The same file written point by point, for clouds that are not in memory
 * as a whole (the dense map of a long run is read back tile by tile): the
 * point count and the coordinate offset are given up front, the header's
 * bounds are filled in by commit(). Throws CloudFileError naming the path
 * (non-finite coordinate, coordinate beyond 32 bits at the scale, a point
 * count other than promised). */
class LasStreamWriter
{
   public:
	LasStreamWriter(const std::string& path, uint64_t points,
	                const Eigen::Vector3d& offset,
	                const LasWriteOptions& o = LasWriteOptions());
	~LasStreamWriter();
	LasStreamWriter(const LasStreamWriter&) = delete;
	LasStreamWriter& operator=(const LasStreamWriter&) = delete;
	void add(const Eigen::Vector3d& xyz, uint16_t intensity,
	         uint8_t classification, float scan_angle_deg, double gps_time_s);
	/** Writes the bounds, flushes and renames into place. */
	void commit();
	/** The offset writeLas uses: the minimum rounded down to a metre. */
	static Eigen::Vector3d offsetFor(const Eigen::Vector3d& min_xyz)
	{
		return min_xyz.array().floor();
	}

   private:
	struct Impl;
	Impl* impl_;
};

/** UNIX seconds -> adjusted standard GPS time (GPS seconds - 1e9), with the
 * 18 leap seconds valid since 2017. */
double unixToAdjustedGpsTime(double unix_s);

/** PLY, ascii or binary_little_endian; the `vertex` element must come first
 * and have x, y, z (float or double). Other vertex properties are skipped,
 * `intensity` (any scalar type) is kept when present. */
PointCloudFile readPly(const std::string& path);

/** PCD v0.7, DATA ascii or binary (not binary_compressed), fields x y z of
 * type F (4 or 8 bytes); `intensity` kept when present. NaN points (organized
 * clouds) are dropped. */
PointCloudFile readPcd(const std::string& path);

/** Dispatches on the extension (.las, .ply, .pcd, case-insensitive). */
PointCloudFile readCloudFile(const std::string& path, bool partial = false);

}  // namespace forest_slam::io
