// Issue 6 "done means": the tiny forest-sim scenario (a 42 m loop walked
// with a handheld VLP-16 + IMU among trees) mapped by `forest-slam map` with
// the lidar-inertial odometry, scored by `forest-eval traj` against the
// simulator's ground truth. The tolerances come from the spread over the
// scenario's seeds 1-6 (this test runs seed 1), not from one run: a change
// that only reshuffles which features are matched moves the figures about
// as much as another seed does. Seeds 1-6 (2026-12-03; with the stem
// model, then without): RPE 0.12-0.15 % both, 0.007-0.008 / 0.006-0.008
// deg/m; ATE 0.010-0.015 m both; end-z 0.016-0.067 % / 0.006-0.037 %;
// return 0.013-0.031 / 0.013-0.027 m and 0.07-0.20 / 0.06-0.18 deg. The
// tolerances sit ~1.5x above the worst seed where that was tight (end-z
// 0.1 %, 4 cm over the loop; return 0.05 m and 0.3 deg). Before this
// design: RPE 3.56 %, end-z 2.9 %, return 1.24 m and 3.3 deg.
#include "sim_accuracy_run.h"

TEST(OdometryOnSim, TinyScenarioAccuracy)
{
	if (!std::filesystem::exists(std::string(FOREST_SLAM_BIN_DIR) +
	                             "/forest-sim"))
		GTEST_SKIP() << "forest-sim is not built";
	std::filesystem::path dir;
	Json::Value j;
	sim_accuracy::mapAndEvaluate("sim-tiny.ini", "vlp16-handheld.ini", "",
	                             "odo_sim", dir, j);
	if (HasFatalFailure()) return;

	// One pose per scan, every scan registered with the IMU.
	EXPECT_EQ(j["association"]["pairs"].asUInt(), 409u);
	EXPECT_LT(j["rpe"]["trans_err_pct"].asDouble(), 0.4);
	EXPECT_LT(j["rpe"]["rot_err_deg_per_m"].asDouble(), 0.025);
	EXPECT_LT(j["ate"]["aligned_se3"]["trans_m"]["rmse"].asDouble(), 0.05);
	EXPECT_LT(std::abs(j["vertical_drift"]["end_pct"].asDouble()), 0.1);
	EXPECT_LT(
	    j["return_to_start"]["estimate_vs_gt"]["total_trans_m"].asDouble(),
	    0.05);
	EXPECT_LT(j["return_to_start"]["estimate_vs_gt"]["angle_deg"].asDouble(),
	          0.3);
	std::filesystem::remove_all(dir);
}
