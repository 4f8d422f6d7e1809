// pcap2rawlog: Velodyne pcap capture -> MRPT rawlog (see doc/ingest.md).
#include <forest_slam/core/log.h>
#include <forest_slam/ingest/pcap_converter.h>

#include <mrpt/core/bits_math.h>

#include <cstdlib>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace
{
const char* kUsage =
    "usage: pcap2rawlog --pcap IN.pcap --model VLP16|HDL32 --out OUT.rawlog "
    "[options]\n"
    "\n"
    "Reads a Velodyne UDP capture with MRPT's CVelodyneScanner: one "
    "observation\n"
    "per revolution (partial first/last revolutions dropped) and position\n"
    "packets as CObservationGPS.\n"
    "\n"
    "  --pcap PATH            input capture (libpcap format)\n"
    "  --model NAME           VLP16 or HDL32\n"
    "  --out PATH             output rawlog (gzip, written atomically)\n"
    "  --calibration FILE     ROS calibration YAML or Velodyne XML (default:\n"
    "                         MRPT's nominal calibration of the model)\n"
    "  --raw                  write CObservationVelodyneScan (raw packets +\n"
    "                         calibration) instead of the decoded\n"
    "                         CObservationRotatingScan the mapping pipeline "
    "reads\n"
    "  --gps-period S         minimum seconds between GPS observations (0.5)\n"
    "  --min-coverage DEG     drop revolutions sweeping less azimuth (350)\n"
    "  --lidar-label L        sensorLabel of the scans (lidar)\n"
    "  --gnss-label L         sensorLabel of the GPS observations (gnss)\n"
    "  --lidar-pose \"x y z yaw pitch roll\"  sensor pose on the vehicle\n"
    "                         [m, deg] (default all 0)\n"
    "  --quiet                no progress bar\n"
    "  --help                 this text\n"
    "\n"
    "Exit codes: 0 ok, 1 runtime error (output keeps what was converted "
    "before\n"
    "the problem), 2 usage error.\n";

int usageError(const std::string& msg)
{
	std::cerr << "pcap2rawlog: " << msg << "\n\n" << kUsage;
	return 2;
}

bool parseNumber(const std::string& s, double& v)
{
	char* end = nullptr;
	v = std::strtod(s.c_str(), &end);
	return !s.empty() && end && *end == '\0' && std::isfinite(v);
}
}  // namespace

int main(int argc, char** argv)
{
	using namespace forest_slam;
	ingest::PcapOptions opts;
	std::string pcap, out, model;
	bool quiet = false;
	const std::vector<std::string> args(argv + 1, argv + argc);
	for (size_t i = 0; i < args.size(); i++)
	{
		const std::string& a = args[i];
		std::string v;
		auto value = [&]()
		{
			if (i + 1 >= args.size()) return false;
			v = args[++i];
			return true;
		};
		double num = 0;
		if (a == "--help" || a == "-h")
		{
			std::cout << kUsage;
			return 0;
		}
		else if (a == "--pcap")
		{
			if (!value()) return usageError("--pcap needs a path");
			pcap = v;
		}
		else if (a == "--out")
		{
			if (!value()) return usageError("--out needs a path");
			out = v;
		}
		else if (a == "--model")
		{
			if (!value()) return usageError("--model needs a name");
			model = v;
		}
		else if (a == "--calibration")
		{
			if (!value()) return usageError("--calibration needs a file");
			opts.calibration_file = v;
		}
		else if (a == "--raw")
			opts.raw_packets = true;
		else if (a == "--quiet")
			quiet = true;
		else if (a == "--gps-period" || a == "--min-coverage")
		{
			if (!value() || !parseNumber(v, num) || num < 0)
				return usageError(a + " needs a non-negative number");
			(a == "--gps-period" ? opts.gps_period_s : opts.min_coverage_deg) =
			    num;
		}
		else if (a == "--lidar-label" || a == "--gnss-label")
		{
			if (!value() || v.empty()) return usageError(a + " needs a label");
			(a == "--lidar-label" ? opts.lidar_label : opts.gnss_label) = v;
		}
		else if (a == "--lidar-pose")
		{
			if (!value())
				return usageError(
				    "--lidar-pose needs \"x y z yaw pitch roll\"");
			std::istringstream is(v);
			std::vector<double> p;
			std::string tok;
			while (is >> tok)
			{
				if (!parseNumber(tok, num))
					return usageError("--lidar-pose: bad number '" + tok + "'");
				p.push_back(num);
			}
			if (p.size() != 6)
				return usageError("--lidar-pose needs 6 numbers");
			opts.lidar_pose =
			    mrpt::poses::CPose3D(p[0], p[1], p[2], mrpt::DEG2RAD(p[3]),
			                         mrpt::DEG2RAD(p[4]), mrpt::DEG2RAD(p[5]));
		}
		else
			return usageError("unknown argument '" + a + "'");
	}
	if (pcap.empty() || out.empty() || model.empty())
		return usageError("--pcap, --model and --out are required");
	if (model != "VLP16" && model != "HDL32")
		return usageError(
		    "--model must be VLP16 or HDL32 (MRPT's pcap reader)");
	opts.model = model;
	if (quiet) core::setLogLevel(core::LogLevel::Warn);
	try
	{
		const auto rep = ingest::convertPcap(pcap, out, opts, !quiet);
		ingest::printPcapReport(rep, std::cout);
		if (!rep.error.empty())
		{
			std::cerr << "pcap2rawlog: " << rep.error << "\n";
			return 1;
		}
		if (rep.revolutions == 0)
		{
			std::cerr << "pcap2rawlog: no complete revolution of " << model
			          << " data in '" << pcap
			          << "' (wrong --model, or not a Velodyne capture?)\n";
			return 1;
		}
		std::cout << "wrote " << out << "\n";
		return 0;
	}
	catch (const std::exception& e)
	{
		std::cerr << "pcap2rawlog: " << e.what() << "\n";
		return 1;
	}
}
