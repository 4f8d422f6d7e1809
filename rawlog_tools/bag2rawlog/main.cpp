// bag2rawlog: ROS 1 / ROS 2 bag -> MRPT rawlog (see doc/ingest.md).
#include <forest_slam/core/config.h>
#include <forest_slam/core/log.h>
#include <forest_slam/ingest/bag_converter.h>

#include <iostream>
#include <string>
#include <vector>

namespace
{
const char* kUsage =
    "usage: bag2rawlog --bag IN --config INI --out OUT.rawlog [--quiet]\n"
    "       bag2rawlog --bag IN --list\n"
    "\n"
    "Converts a ROS 1 bag (.bag) or a ROS 2 bag (folder with metadata.yaml "
    "and\n"
    "sqlite3 .db3 files) into an MRPT rawlog: the lidar topic (PointCloud2 or\n"
    "velodyne_msgs/VelodyneScan), sensor_msgs/Imu and sensor_msgs/NavSatFix,\n"
    "with sensor poses from /tf_static or the INI. Topics, labels and\n"
    "extrinsics come from the INI (ini/bag-*.ini; every key is commented).\n"
    "\n"
    "  --bag PATH      input bag (file or folder)\n"
    "  --config INI    conversion settings\n"
    "  --out PATH      output rawlog (gzip, written atomically)\n"
    "  --list          print topics, types, message counts and rates, then "
    "exit\n"
    "  --quiet         no progress bar, warnings and errors only\n"
    "  --help          this text\n"
    "\n"
    "Exit codes: 0 ok, 1 runtime error (output keeps what was converted "
    "before\n"
    "the problem), 2 usage or configuration error.\n";

int usageError(const std::string& msg)
{
	std::cerr << "bag2rawlog: " << msg << "\n\n" << kUsage;
	return 2;
}
}  // namespace

int main(int argc, char** argv)
{
	using namespace forest_slam;
	std::string bag, config, out;
	bool list = false, quiet = false;
	const std::vector<std::string> args(argv + 1, argv + argc);
	for (size_t i = 0; i < args.size(); i++)
	{
		const std::string& a = args[i];
		auto value = [&](std::string& dst)
		{
			if (i + 1 >= args.size() || args[i + 1].rfind("--", 0) == 0)
				return false;
			dst = args[++i];
			return true;
		};
		if (a == "--help" || a == "-h")
		{
			std::cout << kUsage;
			return 0;
		}
		else if (a == "--bag")
		{
			if (!value(bag)) return usageError("--bag needs a path");
		}
		else if (a == "--config")
		{
			if (!value(config)) return usageError("--config needs a path");
		}
		else if (a == "--out")
		{
			if (!value(out)) return usageError("--out needs a path");
		}
		else if (a == "--list")
			list = true;
		else if (a == "--quiet")
			quiet = true;
		else
			return usageError("unknown argument '" + a + "'");
	}
	if (bag.empty()) return usageError("--bag is required");
	if (quiet) core::setLogLevel(core::LogLevel::Warn);
	try
	{
		if (list)
		{
			if (!config.empty() || !out.empty())
				return usageError("--list takes only --bag");
			auto reader = ingest::BagReader::open(bag);
			ingest::printTopicList(*reader, std::cout);
			return 0;
		}
		if (config.empty() || out.empty())
			return usageError("--config and --out are required (or --list)");
		ingest::Bag2RawlogOptions opts;
		try
		{
			auto cfg = core::TrackedConfig::fromFile(config);
			opts.loadFromConfigFile(cfg);
			cfg.checkNoUnknownKeys();
		}
		catch (const core::ConfigError& e)
		{
			std::cerr << "bag2rawlog: " << e.what() << "\n";
			return 2;
		}
		ingest::ConversionReport report;
		try
		{
			report = ingest::convertBag(bag, out, opts, !quiet);
		}
		catch (const ingest::ConversionSetupError& e)
		{
			std::cerr << "bag2rawlog: " << e.what() << "\n";
			return 1;
		}
		ingest::printReport(report, std::cout);
		if (!report.ok())
		{
			std::cerr << "bag2rawlog: " << report.error << "\n"
			          << "bag2rawlog: '" << out << "' holds the "
			          << report.observations_written
			          << " observations converted before this point\n";
			return 1;
		}
		std::cout << "wrote " << out << "\n";
		return 0;
	}
	catch (const std::exception& e)
	{
		std::cerr << "bag2rawlog: " << e.what() << "\n";
		return 1;
	}
}
