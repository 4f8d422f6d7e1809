// forest-slam: the mapping application. Thin: parses the command line and
// hands over to libs/pipeline. Exit codes: 0 ok, 1 runtime error, 2 usage.
#include "cmd_online.h"
#include "cmd_trees.h"

#include <forest_slam/core/config.h>
#include <forest_slam/core/log.h>
#include <forest_slam/core/memory.h>
#include <forest_slam/outputs/write_outputs.h>
#include <forest_slam/pipeline/mapping_config.h>
#include <forest_slam/pipeline/mapping_job.h>

#include <malloc.h>
#include <pthread.h>

#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace
{
const char* kUsage =
    R"(forest-slam: lidar + IMU forest mapping (MRPT rawlog workflow)

Usage:
  forest-slam map --config FILE.ini --rawlog IN.rawlog --out DIR
                  [--poses TRAJ.tum] [--progress auto|bar|log]
                  [--follow [--follow-timeout S]]
                  [--log-level debug|info|warn|error|quiet]
  forest-slam online --config LIVE.ini --out DIR [--log-level ...]
  forest-slam config --dump --config FILE.ini
  forest-slam trees --cloud FILE.{las,ply,pcd} --out DIR [--config FILE.ini]
  forest-slam --help | forest-slam <command> --help

Commands:
  map      Stream IN.rawlog through the mapping pipeline and write into DIR:
           trajectory.tum (lidar pose per scan, map frame), forest.map
           (serialized CForestMap: edge/planar submaps + tree layer),
           run_summary.json (counts, timing). --poses supplies lidar poses
           (TUM) when the INI says [pipeline] pose_source=trajectory.
           --follow keeps reading IN.rawlog while another process writes
           it; the run ends when it did not grow for --follow-timeout
           seconds (default 10) or on Ctrl-C.
  online   Map from live sensors declared in LIVE.ini like rawlog-grabber
           does (e.g. driver = CVelodyneScanner over UDP), recording every
           observation to DIR/raw.rawlog meanwhile; a status line shows
           scans, latency, queue and drops. Ctrl-C stops grabbing, drains
           the queue and writes the outputs of `map` + online_stats.json
           (doc/online.md).
  config   Print the effective configuration (every key, defaults filled
           in) after checking FILE.ini strictly: unknown keys are errors.
  trees    Detect stems and measure DBH on a cloud from any scanner (TLS,
           other SLAM systems) and write DIR/trees.csv; options from the
           [trees] section of FILE.ini (doc/trees.md).

Exit codes: 0 success, 1 runtime error (bad data, I/O), 2 usage error.
See doc/user-guide.md for the INI keys and output formats.
)";

struct UsageError : std::runtime_error
{
	using std::runtime_error::runtime_error;
};

/** --key value / --flag parsing with a fixed set of allowed options. */
std::map<std::string, std::string> parseOptions(
    const std::vector<std::string>& args, const std::set<std::string>& valued,
    const std::set<std::string>& flags)
{
	std::map<std::string, std::string> out;
	for (size_t i = 0; i < args.size(); i++)
	{
		const auto& a = args[i];
		if (valued.count(a))
		{
			if (i + 1 >= args.size())
				throw UsageError("option " + a + " needs a value");
			out[a] = args[++i];
		}
		else if (flags.count(a))
			out[a] = "1";
		else
			throw UsageError("unknown option '" + a + "'");
	}
	return out;
}

std::string require(const std::map<std::string, std::string>& o,
                    const std::string& key)
{
	const auto it = o.find(key);
	if (it == o.end()) throw UsageError("missing required option " + key);
	return it->second;
}

int cmdMap(const std::vector<std::string>& args)
{
	const auto o =
	    parseOptions(args,
	                 {"--config", "--rawlog", "--out", "--poses", "--progress",
	                  "--log-level", "--follow-timeout"},
	                 {"--help", "--follow"});
	if (o.count("--help"))
	{
		std::cout << kUsage;
		return 0;
	}
	if (o.count("--log-level"))
		forest_slam::core::setLogLevel(
		    forest_slam::core::parseLogLevel(o.at("--log-level")));
	forest_slam::pipeline::MappingJob job;
	job.config_path = require(o, "--config");
	job.rawlog_path = require(o, "--rawlog");
	job.out_dir = require(o, "--out");
	if (o.count("--poses")) job.poses_path = o.at("--poses");
	job.follow = o.count("--follow") > 0;
	if (o.count("--follow-timeout"))
	{
		if (!job.follow) throw UsageError("--follow-timeout needs --follow");
		const auto& v = o.at("--follow-timeout");
		char* end = nullptr;
		job.follow_timeout_s = std::strtod(v.c_str(), &end);
		if (v.empty() || *end || !(job.follow_timeout_s > 0))
			throw UsageError("--follow-timeout expects seconds > 0, got '" + v +
			                 "'");
	}
	if (o.count("--progress"))
	{
		const auto& p = o.at("--progress");
		if (p == "auto")
			job.progress_tty = -1;
		else if (p == "bar")
			job.progress_tty = 1;
		else if (p == "log")
			job.progress_tty = 0;
		else
			throw UsageError("--progress expects auto|bar|log, got '" + p +
			                 "'");
	}
	const auto r = forest_slam::pipeline::runMapping(job);
	const auto& s = r.stats;
	std::printf(
	    "scans: %llu mapped of %llu (empty %llu, out of order %llu, without "
	    "pose %llu, unreadable %llu); imu %llu, gnss %llu\n",
	    (unsigned long long)s.scans_mapped, (unsigned long long)s.scans_in,
	    (unsigned long long)s.scans_empty,
	    (unsigned long long)s.scans_out_of_order,
	    (unsigned long long)s.scans_outside_poses,
	    (unsigned long long)s.scans_unreadable, (unsigned long long)s.imu,
	    (unsigned long long)s.gnss);
	std::printf(
	    "time: %.1f s of data in %.2f s (%.1f scans/s, %.1fx real time)\n",
	    s.dataSeconds(), r.wall_seconds,
	    r.wall_seconds > 0 ? s.scans_mapped / r.wall_seconds : 0.0,
	    r.wall_seconds > 0 ? s.dataSeconds() / r.wall_seconds : 0.0);
	for (const auto& f : r.outputs)
	{
		const auto name = f.substr(f.find_last_of('/') + 1);
		std::printf("wrote %-40s %s\n", f.c_str(),
		            forest_slam::outputs::describeOutput(name).c_str());
	}
	if (r.input_damaged)
	{
		std::fprintf(stderr, "forest-slam: input damaged: %s\n",
		             r.damage_message.c_str());
		return 1;
	}
	return 0;
}

int cmdConfig(const std::vector<std::string>& args)
{
	const auto o = parseOptions(args, {"--config"}, {"--dump", "--help"});
	if (o.count("--help"))
	{
		std::cout << kUsage;
		return 0;
	}
	if (!o.count("--dump"))
		throw UsageError("config: nothing to do (use --dump)");
	const auto cfg =
	    forest_slam::pipeline::MappingConfig::loadFile(require(o, "--config"));
	std::cout << cfg.dump();
	return 0;
}
}  // namespace

int main(int argc, char** argv)
{
	// Transparent huge pages for malloc's blocks (a re-execution with the
	// glibc tunable set; FOREST_SLAM_HUGE_PAGES=0 turns it off, e.g. under
	// valgrind, which does not follow the exec): a fifth less CPU on a VM
	// where page faults are dear (core/memory.h).
	forest_slam::core::useHugePages(argv);
	// The re-execution through /proc/self/exe names the process "exe" in
	// ps, top and perf; its workers are fs-... (run_summary.json
	// scan_thread_cpu_seconds).
	pthread_setname_np(pthread_self(), "forest-slam");
	// Blocks of 4 MB and more (dense-map tile tables, tree-layer columns,
	// detection buffers, the CForestMap's merge) get their own mapping and
	// go back to the system when freed. By default glibc raises this
	// threshold each time such a block is freed, after which they come
	// from the heap and stay in the process once freed (handheld run: RSS
	// peak 1897 MB, 1627 MB with this).
	mallopt(M_MMAP_THRESHOLD, 4 << 20);
	// Setting that threshold also fixes the trim threshold at glibc's
	// 128 kB: whenever more than that lay free at the top of a heap it
	// went back to the system, and the next scan's buffers (a keyframe's
	// voxel table, the local map's rebuilt tables, the tree layer's
	// pending voxels) faulted every page in again: ~420 page faults a
	// scan, the back-end's CPU mostly page faults (handheld, 2000 scans:
	// 830 k -> 430 k faults, back-end 1.75 -> 0.3 ms a scan, system time
	// 11.3 -> 7.9 s). The freed heap goes back every 30 s of data instead
	// (core::releaseFreedHeap in the mapping loop); the end-of-run steps
	// go back to the 128 kB (the mapping pipeline's finish).
	forest_slam::core::setHeapKeptFree(
	    forest_slam::core::kHeapKeptWhileMapping);
	std::vector<std::string> args(argv + 1, argv + argc);
	try
	{
		if (args.empty())
			throw UsageError("missing command (map | online | config | trees)");
		const std::string cmd = args[0];
		const std::vector<std::string> rest(args.begin() + 1, args.end());
		if (cmd == "--help" || cmd == "-h" || cmd == "help")
		{
			std::cout << kUsage;
			return 0;
		}
		if (cmd == "map") return cmdMap(rest);
		if (cmd == "config") return cmdConfig(rest);
		if (cmd == "online")
		{
			try
			{
				return forest_slam::app::cmdOnline(rest, kUsage);
			}
			catch (const forest_slam::app::OnlineUsageError& e)
			{
				throw UsageError(e.what());
			}
		}
		if (cmd == "trees")
		{
			try
			{
				return forest_slam::app::cmdTrees(rest, kUsage);
			}
			catch (const forest_slam::app::TreesUsageError& e)
			{
				throw UsageError(e.what());
			}
		}
		throw UsageError("unknown command '" + cmd +
		                 "' (expected map | online | config | trees)");
	}
	catch (const UsageError& e)
	{
		std::fprintf(stderr, "forest-slam: %s\nRun 'forest-slam --help'.\n",
		             e.what());
		return 2;
	}
	catch (const std::exception& e)
	{
		std::fprintf(stderr, "forest-slam: error: %s\n", e.what());
		return 1;
	}
}
