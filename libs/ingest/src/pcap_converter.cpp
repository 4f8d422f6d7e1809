#include <forest_slam/core/lidar_model.h>
#include <forest_slam/core/log.h>
#include <forest_slam/core/progress.h>
#include <forest_slam/ingest/pcap_converter.h>
#include <forest_slam/ingest/pcap_file.h>
#include <forest_slam/ingest/stamps.h>
#include <forest_slam/io/rawlog_writer.h>

#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/hwdrivers/CVelodyneScanner.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>

namespace forest_slam::ingest
{
namespace
{
/** Time of the first UDP datagram of a classic pcap file [UNIX ns], or -1
 * (pcapng, damaged: MRPT/libpcap will judge). */
int64_t pcapFirstRecordNs(const std::string& path)
{
	try
	{
		PcapFile f(path);
		PcapUdpDatagram d;
		return f.nextUdp(d) ? d.stamp_ns : -1;
	}
	catch (const std::exception&)
	{
		return -1;
	}
}

/** The first damaged record of a classic pcap (file, record, byte offset),
 * or "" if it is whole. MRPT's reader (libpcap) takes a truncated capture
 * for its end without a word, so the converter checks it itself. pcapng and
 * unreadable files are left to MRPT/libpcap to judge. */
std::string pcapDamage(const std::string& path)
{
	std::unique_ptr<PcapFile> f;
	try
	{
		f = std::make_unique<PcapFile>(path);
	}
	catch (const std::exception&)
	{
		return "";
	}
	try
	{
		PcapUdpDatagram d;
		while (f->nextUdp(d))
		{
		}
	}
	catch (const std::exception& e)
	{
		return e.what();
	}
	return "";
}

/** Azimuth swept by a revolution's packets [deg]. */
double coverageDeg(const mrpt::obs::CObservationVelodyneScan& s)
{
	const auto& p = s.scan_packets;
	if (p.empty()) return 0;
	double cdeg = 0;
	for (size_t i = 0; i + 1 < p.size(); i++)
		cdeg += (36000 + p[i + 1].blocks[0].rotation() -
		         p[i].blocks[0].rotation()) %
		        36000;
	cdeg += (36000 + p.back().blocks[11].rotation() -
	         p.back().blocks[0].rotation()) %
	        36000;
	return cdeg * 0.01;
}
}  // namespace

PcapReport convertPcap(const std::string& pcap_path,
                       const std::string& rawlog_path, const PcapOptions& opts,
                       bool show_progress)
{
	if (!std::filesystem::is_regular_file(pcap_path))
		throw std::runtime_error("pcap '" + pcap_path + "' does not exist");
	if (opts.model != "VLP16" && opts.model != "HDL32")
		throw std::runtime_error(
		    "--model '" + opts.model +
		    "': MRPT's pcap reader handles VLP16 and HDL32");
	mrpt::config::CConfigFileMemory cfg;
	const std::string sec = "velodyne";
	cfg.write(sec, "pcap_input", pcap_path);
	cfg.write(sec, "pcap_read_once", "true");
	cfg.write(sec, "pcap_read_fast", "true");
	cfg.write(sec, "pcap_read_full_scan_delay_ms", "0");
	cfg.write(sec, "model", opts.model);
	cfg.write(sec, "pos_packets_min_period", std::to_string(opts.gps_period_s));
	mrpt::hwdrivers::CVelodyneScanner scanner;
	scanner.loadConfig(cfg, sec);
	// Set model and calibration explicitly: the INI "model" key alone left
	// MRPT 2.5.8 with its VLP-16 calibration for an HDL-32 capture.
	scanner.setModelName(opts.model == "HDL32"
	                         ? mrpt::hwdrivers::CVelodyneScanner::HDL32
	                         : mrpt::hwdrivers::CVelodyneScanner::VLP16);
	scanner.setCalibration(
	    toMrpt(opts.calibration_file.empty()
	               ? defaultVelodyneCalibration(opts.model)
	               : loadVelodyneCalibration(opts.calibration_file)));
	scanner.setPCAPVerbosity(false);
	scanner.enableVerbose(false);
	try
	{
		scanner.initialize();
	}
	catch (const std::exception& e)
	{
		throw std::runtime_error("cannot read pcap '" + pcap_path +
		                         "': " + e.what());
	}
	const auto& lm = core::lidarModelByName(opts.model);
	VelodyneDecodeOptions dec = opts.decode;
	if (!(dec.min_range_m > 0)) dec.min_range_m = lm.min_range_m;
	if (!(dec.max_range_m > 0) || dec.max_range_m >= 1e9)
		dec.max_range_m = lm.max_range_m;

	const int64_t capture_ns = pcapFirstRecordNs(pcap_path);
	PcapReport rep;
	io::RawlogWriter writer(rawlog_path, opts.compress_level);
	core::ProgressReporter progress;
	bool have_anchor = false;
	double acc_us = 0;
	uint32_t prev_us = 0;
	try
	{
		for (;;)
		{
			mrpt::obs::CObservationVelodyneScan::Ptr scan;
			mrpt::obs::CObservationGPS::Ptr gps;
			if (!scanner.getNextObservation(scan, gps))
				break;  // end of capture
			if (gps)
			{
				gps->sensorLabel = opts.gnss_label;
				gps->sensorPose = opts.gnss_pose;
				writer.write(*gps);
				rep.gps++;
			}
			if (!scan || scan->scan_packets.empty()) continue;
			// The sensor's microsecond counter gives exact relative times; it
			// is anchored on the capture clock when no GPS time is known
			// (MRPT then stamps scans with the wall clock of the conversion).
			const uint32_t us = scan->scan_packets[0].gps_timestamp();
			if (!have_anchor)
				have_anchor = true;
			else
				acc_us += std::fmod(double(us) - prev_us + 3600e6, 3600e6);
			prev_us = us;
			if (coverageDeg(*scan) < opts.min_coverage_deg)
			{
				rep.partial_dropped++;
				continue;
			}
			if (!scan->has_satellite_timestamp && capture_ns >= 0)
			{
				scan->timestamp =
				    fromUnixNs(capture_ns + std::llround(acc_us * 1e3));
				scan->originalReceivedTimestamp = scan->timestamp;
				rep.clock_from_capture = true;
			}
			scan->sensorLabel = opts.lidar_label;
			scan->sensorPose = opts.lidar_pose;
			uint64_t npts = 0;
			if (opts.raw_packets)
			{
				writer.write(*scan);
				std::vector<VelodynePoint> pts;
				decodeVelodyneScan(*scan, dec, pts);
				npts = pts.size();
			}
			else
			{
				mrpt::obs::CObservationRotatingScan rs;
				OrganizeStats st;
				velodyneToRotatingScan(*scan, rs, dec, &st);
				writer.write(rs);
				npts = st.points_out;
			}
			rep.points += npts;
			rep.min_points =
			    rep.revolutions ? std::min(rep.min_points, npts) : npts;
			rep.max_points = std::max(rep.max_points, npts);
			rep.revolutions++;
			if (show_progress)
				progress.update(rep.revolutions, -1, acc_us * 1e-6);
		}
	}
	catch (const std::exception& e)
	{
		rep.error = "revolution " +
		            std::to_string(rep.revolutions + rep.partial_dropped) +
		            ": " + e.what();
	}
	if (show_progress) progress.finish();
	writer.close();
	if (rep.error.empty())
		if (const auto damage = pcapDamage(pcap_path); !damage.empty())
			rep.error =
			    "capture damaged: " + damage + "; the rawlog holds the " +
			    std::to_string(rep.revolutions) + " revolutions before it";
	return rep;
}

void printPcapReport(const PcapReport& r, std::ostream& os)
{
	os << "summary:\n  revolutions written: " << r.revolutions
	   << "\n  partial revolutions dropped: " << r.partial_dropped
	   << "\n  GPS observations: " << r.gps << "\n  points: " << r.points;
	if (r.revolutions)
		os << " (per revolution " << r.min_points << " .. " << r.max_points
		   << ")";
	os << "\n";
	if (r.clock_from_capture)
		os << "  scans without GPS time are stamped from the capture clock + "
		      "the "
		      "sensor's microsecond counter\n";
	if (!r.error.empty()) os << "  STOPPED: " << r.error << "\n";
}

}  // namespace forest_slam::ingest
