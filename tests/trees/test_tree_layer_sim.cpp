// End to end on the tiny simulated scenario (issue 7): forest-sim ->
// forest-slam map with the ground-truth poses -> trees.csv scored by
// forest-eval trees against gt_trees.csv (trees with DBH >= 10 cm within
// 15 m of the path). The odometry-map figures are printed by
// scripts/bench-trees.sh, not tested here.
#include <gtest/gtest.h>
#include <json/json.h>

#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

namespace fs = std::filesystem;

namespace
{
int run(const std::string& cmd)
{
	const int status = std::system(cmd.c_str());
	return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

Json::Value readJson(const std::string& p)
{
	std::ifstream f(p);
	Json::Value v;
	Json::CharReaderBuilder b;
	std::string errs;
	EXPECT_TRUE(Json::parseFromStream(b, f, &v, &errs)) << p << ": " << errs;
	return v;
}
}  // namespace

TEST(TreeLayerSim, TinyScenarioWithGroundTruthPoses)
{
	const std::string bin = FOREST_SLAM_BIN_DIR;
	const std::string src = FOREST_SLAM_SOURCE_DIR;
	const fs::path dir = fs::temp_directory_path() /
	                     ("forest_trees_sim_" + std::to_string(::getpid()));
	fs::remove_all(dir);
	fs::create_directories(dir);
	const std::string sim = (dir / "sim").string(),
	                  out = (dir / "map").string();
	ASSERT_EQ(
	    run(bin + "/forest-sim --config " + src + "/ini/sim-tiny.ini --out " +
	        sim + " > " + (dir / "sim.log").string() + " 2>&1"),
	    0)
	    << "see " << (dir / "sim.log");

	// The handheld mapping config with the simulator's poses.
	std::ifstream in(src + "/ini/vlp16-handheld.ini");
	std::stringstream ss;
	ss << in.rdbuf();
	const std::string ini =
	    std::regex_replace(ss.str(), std::regex("\npose_source = [a-z]+"),
	                       "\npose_source = trajectory");
	ASSERT_NE(ini.find("\npose_source = trajectory"), std::string::npos);
	std::ofstream((dir / "gt.ini").string()) << ini;
	ASSERT_EQ(
	    run(bin + "/forest-slam map --config " + (dir / "gt.ini").string() +
	        " --rawlog " + sim + "/run.rawlog --poses " + sim +
	        "/gt_trajectory.tum --out " + out + " --progress log > " +
	        (dir / "map.log").string() + " 2>&1"),
	    0)
	    << "see " << (dir / "map.log");
	ASSERT_TRUE(fs::exists(out + "/trees.csv"));

	const std::string json = (dir / "trees.json").string();
	ASSERT_EQ(
	    run(bin + "/forest-eval trees --gt " + sim + "/gt_trees.csv --est " +
	        out + "/trees.csv --max-range-m 15 --traj " + sim +
	        "/gt_trajectory.tum --json " + json + " > " +
	        (dir / "eval.log").string()),
	    0);
	const auto j = readJson(json);
	const auto& d = j["detection"];
	std::printf(
	    "tiny scenario, GT poses: recall %.3f precision %.3f (tp %u fp %u "
	    "fn %u), DBH RMSE %.2f cm bias %+.2f cm MAPE %.2f %%, position "
	    "RMSE %.3f m\n",
	    d["recall"].asDouble(), d["precision"].asDouble(), d["tp"].asUInt(),
	    d["fp"].asUInt(), d["fn"].asUInt(), 100 * j["dbh"]["rmse_m"].asDouble(),
	    100 * j["dbh"]["bias_m"].asDouble(), j["dbh"]["mape_pct"].asDouble(),
	    j["position_err_m"]["rmse"].asDouble());
	EXPECT_GE(d["tp"].asUInt(), 40u);
	EXPECT_GE(d["recall"].asDouble(), 0.95);
	EXPECT_GE(d["precision"].asDouble(), 0.95);
	// Measured: DBH RMSE 0.94 cm, bias +0.08 cm, MAPE 3.0 %, position 0.74
	// cm (before the along-ray fit was trusted up to 60 % of the radius from
	// the orthogonal one: 1.24 cm, -0.18 cm, 4.7 %, 1.16 cm; small stems
	// seen from 10-15 m came out 20-25 % thin; before the along-ray DBH fit
	// and the 1.0-1.6 m band: 1.94 cm, -1.04 cm, 7.7 %, 1.7 cm).
	EXPECT_LE(j["dbh"]["rmse_m"].asDouble(), 0.011);
	EXPECT_LE(std::abs(j["dbh"]["bias_m"].asDouble()), 0.003);
	EXPECT_LE(j["dbh"]["mape_pct"].asDouble(), 3.8);
	EXPECT_LE(j["position_err_m"]["rmse"].asDouble(), 0.01);

	// The tree layer's cost is reported per stage.
	const auto s = readJson(out + "/run_summary.json");
	EXPECT_TRUE(s["stage_ms"].isMember("trees"));
	EXPECT_GT(s["tree_layer"]["detections"].asUInt(), 0u);
	// Its CPU time (thread clocks, both threads of the end-of-run
	// detections) is part of the process's, and its share below 1.
	const double cpu_ms = s["tree_layer"]["cpu_ms"].asDouble();
	EXPECT_GT(cpu_ms, 0.0);
	EXPECT_LT(cpu_ms, 1000 * s["cpu_seconds"].asDouble());
	EXPECT_NEAR(s["tree_layer"]["share_of_cpu"].asDouble(),
	            cpu_ms / (1000 * s["cpu_seconds"].asDouble()), 1e-3);
	// The updates' part of it: a recorded run detects its stems at the end
	// (finish), so the updates cost less than the whole, but not nothing.
	const double update_ms = s["tree_layer"]["update_cpu_ms"].asDouble();
	EXPECT_GT(update_ms, 0.0);
	EXPECT_LT(update_ms, cpu_ms);
	EXPECT_NEAR(s["tree_layer"]["update_share_of_cpu"].asDouble(),
	            update_ms / (1000 * s["cpu_seconds"].asDouble()), 1e-3);
	EXPECT_EQ(s["trees"].asUInt(), j["inputs"]["est_trees"].asUInt());
	if (!HasFailure()) fs::remove_all(dir);
}
