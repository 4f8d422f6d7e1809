#pragma once
// Velodyne raw packets (velodyne_msgs/VelodyneScan, pcap, MRPT's
// CObservationVelodyneScan) to points and to CObservationRotatingScan.
//
// Why our own decoder: MRPT 2.5.8's CObservationVelodyneScan::
// generatePointCloud() and CObservationRotatingScan::fromVelodyne() read only
// returns 0..15 of each 32-return block (a VLP-16 loses its second firing, an
// HDL-32E its lasers 16..31), ignore per-laser azimuth corrections, know no
// VLP-32C, and fromVelodyne() writes a grid that core::unpackRotatingScan()
// cannot read (see doc/ingest.md). The geometry here follows the Velodyne
// manuals and the ROS drivers (velodyne_pointcloud, nebula): ROS axes
// (x forward, y left, z up), per-laser vertical/rotational/distance/offset
// corrections, and each return's azimuth interpolated between its block's
// and the next block's azimuth by its firing time (VLP-16: 16 lasers per
// firing, 2.304 us apart, two firings per block; HDL-32E: 32 lasers 1.152 us
// apart; VLP-32C: 16 pairs of simultaneous lasers 2.304 us apart), rounded
// to the 0.01 deg grid as the drivers do.
#include <forest_slam/ingest/messages.h>
#include <forest_slam/ingest/scan_organizer.h>

#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/obs/CObservationVelodyneScan.h>
#include <mrpt/obs/VelodyneCalibration.h>

#include <cstdint>
#include <string>
#include <vector>

namespace forest_slam::ingest
{
struct VelodyneLaserCalib
{
	double vert_rad = 0;  ///< elevation
	double rot_rad = 0;   ///< azimuth correction (subtracted)
	double dist_m = 0;    ///< added to every non-zero range
	double vert_offset_m = 0, horiz_offset_m = 0;
};

struct VelodyneCalib
{
	std::vector<VelodyneLaserCalib> lasers;  ///< index = laser id
	/** 0 = the model's (2 mm; 4 mm for the VLP-32C). */
	double distance_resolution_m = 0;
	std::string source;  ///< file name or "MRPT default VLP16"...
};

/** ROS calibration YAML (velodyne_pointcloud / nebula: "lasers:" list with
 * laser_id, rot_correction, vert_correction [rad], dist_correction,
 * vert_offset_correction, horiz_offset_correction [m]; optional
 * distance_resolution) or Velodyne XML (db.xml, through MRPT). Throws
 * std::runtime_error naming the file and the problem. */
VelodyneCalib loadVelodyneCalibration(const std::string& path);
/** MRPT's built-in calibration for "VLP16", "HDL32" (and aliases); throws
 * std::invalid_argument for models MRPT has none for (e.g. VLP32C). */
VelodyneCalib defaultVelodyneCalibration(const std::string& model);
mrpt::obs::VelodyneCalibration toMrpt(const VelodyneCalib& c);
VelodyneCalib fromMrpt(const mrpt::obs::VelodyneCalibration& c);

/** Model id byte of a data packet (offset 1205). */
enum VelodyneModelId : uint8_t
{
	kHdl32e = 0x21,
	kVlp16 = 0x22,
	kVlp16HiRes = 0x24,
	kVlp32c = 0x28
};
/** core::LidarModel name for a model id byte; "" if unsupported. */
std::string lidarModelForVelodyneId(uint8_t model_id);
/** The model to decode with: the packets' model byte, or, when it is not a
 * known one (early VLP-16/HDL-32E firmware leaves it 0), the model a 16- or
 * 32-laser calibration implies. 0 if neither tells. */
uint8_t resolveVelodyneModel(uint8_t model_byte, size_t calibration_lasers);

enum class DualReturn
{
	Strongest,
	Last,
	Both
};
DualReturn parseDualReturn(const std::string& s);  ///< throws invalid_argument

struct VelodyneDecodeOptions
{
	double min_range_m = 0.0;  ///< exclusive, as the ROS drivers
	double max_range_m = 1e9;  ///< exclusive
	DualReturn dual = DualReturn::Strongest;
};

struct VelodynePoint
{
	float x = 0, y = 0, z = 0;  ///< sensor frame, ROS axes
	float distance_m = 0;
	uint8_t intensity = 0;
	uint16_t laser_id = 0;
	uint16_t azimuth_cdeg = 0;  ///< Velodyne azimuth, 0.01 deg, clockwise
	uint8_t block = 0;          ///< data block within its packet (0..11)
	uint8_t return_index = 0;   ///< position within the block (0..31)
	uint32_t packet = 0;        ///< packet index within the scan
	double t_s = 0;             ///< after the first firing of the first packet
};

/** Decodes packets (raw 1206-byte payloads) in order. Times come from each
 * packet's own microsecond counter (unwrapped at the hour) plus the firing
 * offset within the packet. Throws std::runtime_error naming the packet
 * index for unsupported models or a calibration with too few lasers. */
void decodeVelodynePackets(const std::vector<const uint8_t*>& packets,
                           const VelodyneCalib& calib,
                           const VelodyneDecodeOptions& opts,
                           std::vector<VelodynePoint>& out);
/** Same, for the packets held by an MRPT observation (its calibration is used
 * if not empty, else MRPT's default for the model). */
void decodeVelodyneScan(const mrpt::obs::CObservationVelodyneScan& scan,
                        const VelodyneDecodeOptions& opts,
                        std::vector<VelodynePoint>& out);

/** A CObservationRotatingScan as core::unpackRotatingScan() expects it:
 * rows = laser id, lidarModel from the packets' model byte, points placed by
 * their true azimuth. Copies timestamp, sensorLabel, sensorPose. This is the
 * conversion to use instead of MRPT's fromVelodyne(). */
void velodyneToRotatingScan(const mrpt::obs::CObservationVelodyneScan& in,
                            mrpt::obs::CObservationRotatingScan& out,
                            const VelodyneDecodeOptions& opts = {},
                            OrganizeStats* stats = nullptr);

/** Builds an MRPT observation from a ROS velodyne_msgs/VelodyneScan.
 * timestamp = first packet's stamp. */
void velodyneScanFromMsg(const VelodyneScanMsg& msg, const VelodyneCalib& calib,
                         mrpt::obs::CObservationVelodyneScan& out);

}  // namespace forest_slam::ingest
