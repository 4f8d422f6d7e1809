// Shared by the end-to-end odometry accuracy tests: generate a forest-sim
// scenario, map it with `forest-slam map` and an INI of ini/, score the
// trajectory with `forest-eval traj`, hand back its JSON report.
#pragma once

#include <gtest/gtest.h>
#include <json/json.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace sim_accuracy
{
inline int run(const std::string& cmd)
{
	const int status = std::system(cmd.c_str());
	return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/** Runs forest-sim with ini/SIM_INI (seed 1), then forest-slam map with
 * ini/SLAM_INI followed by EXTRA_INI (later sections override: e.g. outputs
 * off to save time), then forest-eval traj. Fills `report` with traj.json;
 * `dir` is the scratch folder (removed by the caller on success). Fatal
 * gtest failures on any step, naming the log to read. */
inline void mapAndEvaluate(const std::string& sim_ini,
                           const std::string& slam_ini,
                           const std::string& extra_ini, const std::string& tag,
                           std::filesystem::path& dir, Json::Value& report)
{
	namespace fs = std::filesystem;
	const std::string bin = FOREST_SLAM_BIN_DIR, src = FOREST_SLAM_SOURCE_DIR;
	dir = fs::temp_directory_path() /
	      ("fs_" + tag + "_" + std::to_string(::getpid()));
	fs::remove_all(dir);
	fs::create_directories(dir);
	const std::string d = dir.string();
	{
		std::ifstream in(src + "/ini/" + slam_ini);
		std::ofstream out(d + "/slam.ini");
		ASSERT_TRUE(in && out);
		out << in.rdbuf() << "\n" << extra_ini << "\n";
	}
	ASSERT_EQ(run(bin + "/forest-sim --config " + src + "/ini/" + sim_ini +
	              " --seed 1 --out " + d + "/sim > " + d + "/sim.log 2>&1"),
	          0)
	    << "see " << d << "/sim.log";
	ASSERT_EQ(
	    run(bin + "/forest-slam map --config " + d + "/slam.ini --rawlog " + d +
	        "/sim/run.rawlog --out " + d + "/map > " + d + "/map.log 2>&1"),
	    0)
	    << "see " << d << "/map.log";
	ASSERT_EQ(run(bin + "/forest-eval traj --gt " + d +
	              "/sim/gt_trajectory.tum --est " + d +
	              "/map/trajectory.tum --json " + d + "/traj.json > /dev/null"),
	          0);
	std::ifstream f(d + "/traj.json");
	Json::CharReaderBuilder b;
	std::string errs;
	ASSERT_TRUE(Json::parseFromStream(b, f, &report, &errs)) << errs;
}
}  // namespace sim_accuracy
