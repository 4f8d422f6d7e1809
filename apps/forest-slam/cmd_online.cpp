// forest-slam online --config FILE.ini --out DIR [--log-level L]
// Live sensors declared in FILE.ini (doc/online.md) -> the mapping pipeline,
// recorded to DIR/raw.rawlog at the same time; Ctrl-C stops, drains the
// queue and writes every output.
#include "cmd_online.h"

#include <forest_slam/core/log.h>
#include <forest_slam/online/online_job.h>

#include <cstdio>
#include <iostream>

namespace forest_slam::app
{
int cmdOnline(const std::vector<std::string>& args, const char* usage)
{
	online::OnlineJob job;
	for (size_t i = 0; i < args.size(); i++)
	{
		const auto& a = args[i];
		if (a == "--help")
		{
			std::cout << usage;
			return 0;
		}
		if (a != "--config" && a != "--out" && a != "--log-level")
			throw OnlineUsageError("unknown option '" + a + "'");
		if (i + 1 >= args.size())
			throw OnlineUsageError("option " + a + " needs a value");
		const auto& v = args[++i];
		if (a == "--config")
			job.config_path = v;
		else if (a == "--out")
			job.out_dir = v;
		else
			core::setLogLevel(core::parseLogLevel(v));
	}
	if (job.config_path.empty())
		throw OnlineUsageError("missing required option --config");
	if (job.out_dir.empty())
		throw OnlineUsageError("missing required option --out");

	const auto r = online::runOnline(job);
	const auto& s = r.mapping.stats;
	const auto lat = online::Spread::of(r.live.latency_ms);
	std::printf(
	    "scans: %llu captured, %llu processed (%llu mapped, %llu light), %llu "
	    "dropped from the pipeline queue; imu %llu, gnss %llu\n",
	    (unsigned long long)r.live.scans_captured,
	    (unsigned long long)r.live.scans_processed,
	    (unsigned long long)s.scans_mapped, (unsigned long long)s.scans_light,
	    (unsigned long long)r.live.scans_dropped, (unsigned long long)s.imu,
	    (unsigned long long)s.gnss);
	if (r.live.scans_unprocessed > 0)
		std::printf(
		    "scans left unprocessed by a second stop signal: %llu (in "
		    "raw.rawlog)\n",
		    (unsigned long long)r.live.scans_unprocessed);
	std::printf(
	    "latency capture -> pose: median %.0f ms, p95 %.0f ms, max %.0f ms\n",
	    lat.median, lat.p95, lat.max);
	if (r.live.velodyne_packets > 0)
		std::printf("velodyne data packets in the scans: %llu\n",
		            (unsigned long long)r.live.velodyne_packets);
	std::printf(
	    "recorded: %llu of %llu observations (%.1f MB) to %s/raw.rawlog\n",
	    (unsigned long long)r.live.recorded,
	    (unsigned long long)r.live.observations_captured,
	    r.live.recorded_bytes / 1e6, job.out_dir.c_str());
	for (const auto& f : r.mapping.outputs)
		std::printf("wrote %s\n", f.c_str());
	if (!r.recording_error.empty())
	{
		std::fprintf(stderr, "forest-slam: raw recording failed: %s\n",
		             r.recording_error.c_str());
		return 1;
	}
	return 0;
}

}  // namespace forest_slam::app
