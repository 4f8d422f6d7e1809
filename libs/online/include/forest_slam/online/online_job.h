#pragma once
// `forest-slam online`: live sensors -> the same loop and outputs as an
// offline run (pipeline::runMapping), plus raw.rawlog and online_stats.json.
#include <forest_slam/online/live_source.h>
#include <forest_slam/pipeline/mapping_job.h>

#include <string>

namespace forest_slam::online
{
struct OnlineJob
{
	std::string config_path;
	std::string out_dir;
};

struct OnlineResult
{
	pipeline::MappingResult mapping;
	LiveStats live;
	std::string recording_error;  ///< empty unless raw.rawlog failed
};

/** Runs until SIGINT/SIGTERM, the end of replayed files, or [online]
 * idle_timeout_s; then stops grabbing, drains the queue and writes every
 * output. Throws core::ConfigError / std::runtime_error for problems found
 * before grabbing starts (bad INI, UDP port in use, raw.rawlog exists). */
OnlineResult runOnline(const OnlineJob& job);

}  // namespace forest_slam::online
