// forest-sim: synthetic forest + sensors + ground truth. Thin: parses the
// command line and hands over to libs/sim. Exit codes: 0 ok, 1 runtime
// error, 2 usage error.
#include <forest_slam/core/config.h>
#include <forest_slam/core/log.h>
#include <forest_slam/sim/options.h>
#include <forest_slam/sim/simulator.h>

#include <cstdio>
#include <iostream>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace
{
const char* kUsage =
    R"(forest-sim: simulated forest, lidar, IMU and GNSS with ground truth

Usage:
  forest-sim --config FILE.ini --out DIR [--seed N] [--bag DIR/run.bag]
             [--threads N] [--progress auto|bar|log]
             [--log-level debug|info|warn|error|quiet]
  forest-sim --config FILE.ini --dump-config [--seed N]
  forest-sim --help

Writes into DIR:
  run.rawlog         gzip MRPT rawlog: CObservationRotatingScan per revolution
                     ("lidar", with gt_label/gt_tree range layers), IMU
                     ("imu", 200 Hz) and GNSS ("gnss", 1 Hz), in time order
  gt_trajectory.tum  lidar pose at [output] gt_rate_hz, map frame
  gt_trees.csv       id,x,y,z_ground,dbh_m,height_m,lean_deg,sapling (map)
  gnss_map.csv       the GNSS fixes in the map frame (t,x,y,z,...)
  scenario.ini       effective parameters + [ground_truth] (frames, counts)
--bag also writes the run as a ROS1 bag (/velodyne_points, /imu/data,
/gps/fix, /tf_static). The same config and seed give identical files.
--seed overrides [sim] seed, --threads [sim] threads (the output does not
depend on it). --dump-config prints the effective parameters.

Exit codes: 0 success, 1 runtime error, 2 usage or configuration error.
See doc/simulator.md for the scenarios, every INI key and the outputs.
)";

struct UsageError : std::runtime_error
{
	using std::runtime_error::runtime_error;
};

std::map<std::string, std::string> parseOptions(
    const std::vector<std::string>& args)
{
	const std::set<std::string> valued = {
	    "--config",  "--out",      "--seed",     "--bag",
	    "--threads", "--progress", "--log-level"};
	const std::set<std::string> flags = {"--help", "-h", "--dump-config"};
	std::map<std::string, std::string> out;
	for (size_t i = 0; i < args.size(); i++)
	{
		const auto& a = args[i];
		if (valued.count(a))
		{
			if (i + 1 >= args.size())
				throw UsageError("option " + a + " needs a value");
			if (out.count(a)) throw UsageError("option " + a + " given twice");
			out[a] = args[++i];
		}
		else if (flags.count(a))
			out[a == "-h" ? "--help" : a] = "1";
		else
			throw UsageError("unknown option '" + a + "'");
	}
	return out;
}

uint64_t parseCount(const std::string& option, const std::string& s)
{
	try
	{
		return forest_slam::core::parseConfigValue<uint64_t>(s, option);
	}
	catch (const std::exception&)
	{
		throw UsageError(option + " expects a non-negative integer, got '" + s +
		                 "'");
	}
}
}  // namespace

int main(int argc, char** argv)
{
	using namespace forest_slam;
	const std::vector<std::string> args(argv + 1, argv + argc);
	try
	{
		const auto o = parseOptions(args);
		if (o.count("--help"))
		{
			std::cout << kUsage;
			return 0;
		}
		if (o.count("--log-level"))
		{
			try
			{
				core::setLogLevel(core::parseLogLevel(o.at("--log-level")));
			}
			catch (const std::invalid_argument& e)
			{
				throw UsageError(e.what());
			}
		}
		if (!o.count("--config"))
			throw UsageError("missing required option --config");
		sim::SimOptions opts;
		try
		{
			opts = sim::SimOptions::loadFile(o.at("--config"));
		}
		catch (const core::ConfigError& e)
		{
			std::fprintf(stderr, "forest-sim: configuration error: %s\n",
			             e.what());
			return 2;
		}
		if (o.count("--seed"))
			opts.run.seed = parseCount("--seed", o.at("--seed"));
		if (o.count("--threads"))
		{
			const uint64_t n = parseCount("--threads", o.at("--threads"));
			if (n < 1 || n > 64)
				throw UsageError("--threads expects 1..64, got '" +
				                 o.at("--threads") + "'");
			opts.run.threads = static_cast<int>(n);
		}
		if (o.count("--dump-config"))
		{
			std::cout << opts.toIni();
			return 0;
		}
		if (!o.count("--out"))
			throw UsageError("missing required option --out");
		sim::RunRequest req;
		req.out_dir = o.at("--out");
		if (o.count("--bag")) req.bag_path = o.at("--bag");
		if (o.count("--progress"))
		{
			const auto& p = o.at("--progress");
			if (p == "auto")
				req.progress_tty = -1;
			else if (p == "bar")
				req.progress_tty = 1;
			else if (p == "log")
				req.progress_tty = 0;
			else
				throw UsageError("--progress expects auto|bar|log, got '" + p +
				                 "'");
		}
		const auto r = sim::runSimulation(opts, req);
		std::printf(
		    "scenario: %s, seed %llu: %.1f s of data, route %.0f m, %d trees "
		    "(%.0f stems/ha), %d saplings, %d shrubs (cover %.0f %%)\n",
		    opts.motion.type.c_str(),
		    static_cast<unsigned long long>(opts.run.seed), r.duration_s,
		    r.path_length_m, r.stats.trees, r.stats.stems_per_ha,
		    r.stats.saplings, r.stats.shrubs, 100 * r.stats.shrub_cover);
		std::printf(
		    "data: %zu scans (%llu points), %zu IMU, %zu GNSS epochs (%zu "
		    "fixes)\n",
		    r.scans, static_cast<unsigned long long>(r.points), r.imu, r.gnss,
		    r.gnss_fixes);
		std::printf(
		    "speed: %.1f scans/s ray casting (%d threads), %.1f s total\n",
		    r.scansPerSecond(), opts.run.threads, r.total_wall_s);
		for (const auto& f : r.outputs) std::printf("wrote %s\n", f.c_str());
		return 0;
	}
	catch (const UsageError& e)
	{
		std::fprintf(stderr, "forest-sim: %s\nRun 'forest-sim --help'.\n",
		             e.what());
		return 2;
	}
	catch (const std::exception& e)
	{
		std::fprintf(stderr, "forest-sim: error: %s\n", e.what());
		return 1;
	}
}
