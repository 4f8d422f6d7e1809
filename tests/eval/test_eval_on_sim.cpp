// forest-eval on the simulator's own ground-truth files (issue 3, "forest-sim
// + forest-eval run in the test suite"): checks that the two halves agree on
// the file formats and frames. Estimates are the GT with known errors, so the
// expected figures are known exactly. Skipped until forest-sim and
// ini/sim-tiny.ini exist in this build.
#include <forest_slam/eval/tree_metrics.h>
#include <forest_slam/io/tum.h>
#include <gtest/gtest.h>
#include <json/json.h>

#include <sys/wait.h>

#include <cmath>
#include <filesystem>
#include <fstream>

using namespace forest_slam;
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

TEST(EvalOnSim, SimulatorGroundTruthWithKnownErrors)
{
	const std::string sim = std::string(FOREST_SLAM_BIN_DIR) + "/forest-sim";
	const std::string eval = std::string(FOREST_SLAM_BIN_DIR) + "/forest-eval";
	const std::string ini =
	    std::string(FOREST_SLAM_SOURCE_DIR) + "/ini/sim-tiny.ini";
	if (!fs::exists(sim) || !fs::exists(ini))
		GTEST_SKIP() << "needs " << sim << " and " << ini;
	const fs::path dir = fs::temp_directory_path() /
	                     ("forest_eval_sim_" + std::to_string(::getpid()));
	fs::remove_all(dir);
	fs::create_directories(dir);
	const std::string out = (dir / "sim").string();
	ASSERT_EQ(run(sim + " --config " + ini + " --seed 3 --out " + out + " > " +
	              (dir / "sim.log").string() + " 2>&1"),
	          0)
	    << "see " << (dir / "sim.log");

	// Trajectory: every 10th GT pose, climbing 0.1 % of the distance
	// travelled -> vertical drift at the end is exactly 0.1 %.
	const auto gt = io::readTum(out + "/gt_trajectory.tum");
	ASSERT_GT(gt.size(), 20u);
	core::Trajectory est;
	double d = 0;
	for (size_t i = 0; i < gt.size(); i += 10)
	{
		if (!est.empty())
			d += (gt[i].pose.translation() - gt[i - 10].pose.translation())
			         .norm();
		core::StampedPose p = gt[i];
		p.pose.translation().z() += 0.001 * d;
		est.push_back(p);
	}
	ASSERT_GT(d, 1.0);
	io::writeTum((dir / "est.tum").string(), est);
	const std::string tj = (dir / "traj.json").string();
	ASSERT_EQ(
	    run(eval + " traj --gt " + out + "/gt_trajectory.tum --est " +
	        (dir / "est.tum").string() + " --json " + tj + " > /dev/null"),
	    0);
	const auto j = readJson(tj);
	EXPECT_EQ(j["association"]["pairs"].asUInt(), est.size());
	EXPECT_NEAR(j["vertical_drift"]["distance_m"].asDouble(), d, 1e-4 * d);
	EXPECT_NEAR(j["vertical_drift"]["end_pct"].asDouble(), 0.1, 1e-3);
	EXPECT_NEAR(j["return_to_start"]["estimate_vs_gt"]["z_m"].asDouble(),
	            0.001 * d, 1e-4);

	// Trees: the evaluated GT trees, 1 cm too thick and 5 cm east.
	const auto trees = eval::readTreesCsv(out + "/gt_trees.csv");
	std::ofstream f((dir / "est.csv").string());
	f << "id,x,y,dbh_m\n";
	f.precision(10);
	size_t n = 0;
	double ape = 0;
	for (const auto& t : trees)
	{
		if (t.sapling || t.dbh_m < 0.10) continue;
		f << "e" << t.id << "," << t.x + 0.05 << "," << t.y << ","
		  << t.dbh_m + 0.01 << "\n";
		ape += 0.01 / t.dbh_m;
		n++;
	}
	f.close();
	ASSERT_GT(n, 0u) << "sim-tiny has no tree of DBH >= 10 cm";
	const std::string tr = (dir / "trees.json").string();
	ASSERT_EQ(
	    run(eval + " trees --gt " + out + "/gt_trees.csv --est " +
	        (dir / "est.csv").string() + " --json " + tr + " > /dev/null"),
	    0);
	const auto t = readJson(tr);
	EXPECT_EQ(t["detection"]["tp"].asUInt(), n);
	EXPECT_EQ(t["detection"]["fp"].asUInt(), 0u);
	EXPECT_DOUBLE_EQ(t["detection"]["recall"].asDouble(), 1.0);
	EXPECT_NEAR(t["dbh"]["bias_m"].asDouble(), 0.01, 1e-8);
	EXPECT_NEAR(t["dbh"]["rmse_m"].asDouble(), 0.01, 1e-8);
	EXPECT_NEAR(t["dbh"]["mape_pct"].asDouble(), 100 * ape / n, 1e-6);
	EXPECT_NEAR(t["position_err_m"]["rmse"].asDouble(), 0.05, 1e-8);
	if (!HasFailure()) fs::remove_all(dir);
}
