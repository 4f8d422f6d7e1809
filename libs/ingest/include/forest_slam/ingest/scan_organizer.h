#pragma once
// Builds a CObservationRotatingScan (range image, rows = laser id in the
// lidar model's native order, columns = firing azimuth) from unorganized
// lidar points that carry a ring number and, ideally, a per-point time.
//
// The column grid follows core::columnAzimuth/columnTime: column c has
// azimuth startAzimuth + azimuthSpan*c/(n-1) and time sweepDuration*c/(n-1).
// The grid spacing and phase are estimated from the points themselves
// (median azimuth step within a ring, refined by least squares), so a cloud
// that was generated from a range image maps back onto the same grid, and
// a real sensor's returns land in the column nearest their true azimuth. The
// sweep may span a little more than 360 degrees when lasers have azimuth
// offsets (VLP-32C): those returns keep both their direction and their time.
#include <forest_slam/core/lidar_model.h>
#include <forest_slam/ingest/pointcloud2.h>

#include <mrpt/obs/CObservationRotatingScan.h>

#include <cstdint>
#include <string>
#include <vector>

namespace forest_slam::ingest
{
/** How the cloud's ring numbers map to the model's rows (laser ids). */
enum class RingOrder
{
	Auto,    ///< decided once from the measured elevation of each ring
	Native,  ///< ring = laser id (MRPT, Ouster)
	ElevationAscending,  ///< ring 0 = lowest beam (ROS velodyne driver)
	ElevationDescending  ///< ring 0 = highest beam
};
RingOrder parseRingOrder(const std::string& s);  ///< throws invalid_argument
const char* ringOrderName(RingOrder r);

struct OrganizerOptions
{
	std::string lidar_model = "VLP16";
	RingOrder ring_order = RingOrder::Auto;
	/** Range quantization; uint16 ranges reach 65535*resolution. */
	double range_resolution_m = 0.002;
	/** Used only when points carry no time: revolutions per second. */
	double rate_hz = 10.0;
	/** +1 counter-clockwise, -1 clockwise (seen from above), 0 = from data
	 * (falls back to clockwise, as Velodyne, Ouster and Hesai spin). */
	int rotation_sign = 0;
	/** 0: keep the model's range limits. */
	double min_range_m = 0, max_range_m = 0;
};

struct OrganizeStats
{
	size_t points_in = 0, points_out = 0;
	size_t out_of_range = 0;  ///< beyond [min,max] range or uint16 range
	size_t collisions = 0;    ///< second return for an occupied cell (dropped)
	double max_time_error_s = 0;  ///< |point time - column time|
};

class ScanOrganizer
{
   public:
	explicit ScanOrganizer(const OrganizerOptions& opts);
	const core::LidarModel& model() const { return *model_; }
	/** The ring order in use (Auto is resolved by the first organize()). */
	RingOrder ringOrder() const { return ring_order_; }

	/** `stamp_ns` is the time points' t_s are relative to; `has_time` says
	 * whether t_s is meaningful. Fills the range image, grid, sweep
	 * duration, lidarModel, min/maxRange and timestamp (= time of column 0);
	 * leaves sensorLabel and sensorPose to the caller. Throws
	 * std::runtime_error if rings exceed the model or (Auto) the measured
	 * elevations do not fit the model in any order. */
	void organize(const std::vector<CloudPoint>& pts, int64_t stamp_ns,
	              bool has_time, mrpt::obs::CObservationRotatingScan& out,
	              OrganizeStats* stats = nullptr);

   private:
	OrganizerOptions opts_;
	const core::LidarModel* model_;
	RingOrder ring_order_;
	std::vector<int> row_of_ring_;
	void resolveRingOrder(const std::vector<CloudPoint>& pts);
};

}  // namespace forest_slam::ingest
