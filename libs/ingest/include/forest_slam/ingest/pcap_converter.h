#pragma once
// pcap2rawlog's engine: a Wireshark/tcpdump capture of a Velodyne's UDP
// traffic, read by MRPT's CVelodyneScanner (one observation per revolution,
// position packets as CObservationGPS), written as a rawlog.
#include <forest_slam/ingest/velodyne.h>

#include <mrpt/poses/CPose3D.h>

#include <cstdint>
#include <ostream>
#include <string>

namespace forest_slam::ingest
{
struct PcapOptions
{
	std::string model = "VLP16";  ///< VLP16 or HDL32 (CVelodyneScanner's)
	/** Optional calibration (ROS YAML or Velodyne XML); default: MRPT's. */
	std::string calibration_file;
	/** true: CObservationVelodyneScan (raw packets); false: decoded
	 * CObservationRotatingScan as the mapping pipeline reads. */
	bool raw_packets = false;
	/** Minimum period between GPS observations from position packets. */
	double gps_period_s = 0.5;
	/** Revolutions covering less azimuth (the capture's first and last) are
	 * dropped. */
	double min_coverage_deg = 350;
	std::string lidar_label = "lidar", gnss_label = "gnss";
	mrpt::poses::CPose3D lidar_pose, gnss_pose;
	VelodyneDecodeOptions decode;  ///< ranges 0 = the model's
	int compress_level = 1;
};

struct PcapReport
{
	uint64_t revolutions = 0, partial_dropped = 0, gps = 0;
	uint64_t points = 0;  ///< decoded points written (RotatingScan output)
	uint64_t min_points = 0, max_points = 0;  ///< per revolution
	bool clock_from_capture = false;          ///< no GPS time: pcap clock used
	std::string error;  ///< empty on success; output holds what came before
};

/** Throws std::runtime_error if the pcap cannot be opened or the options are
 * wrong (nothing written); later problems set report.error. */
PcapReport convertPcap(const std::string& pcap_path,
                       const std::string& rawlog_path, const PcapOptions& opts,
                       bool show_progress = true);
void printPcapReport(const PcapReport& r, std::ostream& os);

}  // namespace forest_slam::ingest
