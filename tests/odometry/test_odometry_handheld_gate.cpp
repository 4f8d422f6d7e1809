// Accuracy gate for the handheld odometry (issue 6): a 105 m walk through
// the stand of ini/sim-handheld.ini (slopes, saplings, shrubs, leaning
// stems; ini/sim-handheld-short.ini, 967 scans) mapped with
// ini/vlp16-handheld.ini, outputs off. The tiny scenario is too small to see
// drift: it passed while a units bug in the degeneracy test had the
// handheld RPE at 5.9 %. Figures when written: RPE 0.104 %, 0.0023 deg/m,
// ATE 0.021 m, vertical drift 0.002 %, return to start 0.038 m / 0.15 deg
// (with a constant-velocity deskew: 0.17 %, 0.0054 deg/m, 0.033 m);
// tolerances about 2x above.
#include "sim_accuracy_run.h"

TEST(OdometryOnSim, ShortHandheldWalkAccuracy)
{
	if (!std::filesystem::exists(std::string(FOREST_SLAM_BIN_DIR) +
	                             "/forest-sim"))
		GTEST_SKIP() << "forest-sim is not built";
	std::filesystem::path dir;
	Json::Value j;
	sim_accuracy::mapAndEvaluate(
	    "sim-handheld-short.ini", "vlp16-handheld.ini",
	    "[outputs]\nkeyframes_simplemap = false\nforest_map = false\n"
	    "las = false\noctomap_bt = false\ntrees_csv = false\n"
	    "trees_geojson = false\ndtm_asc = false\nreport_html = false\n"
	    "trajectory_kitti = false\n[trees]\nlayer_enabled = false\n",
	    "odo_gate", dir, j);
	if (HasFatalFailure()) return;

	EXPECT_EQ(j["association"]["pairs"].asUInt(), 967u);
	EXPECT_LT(j["rpe"]["trans_err_pct"].asDouble(), 0.2);
	EXPECT_LT(j["rpe"]["rot_err_deg_per_m"].asDouble(), 0.0045);
	EXPECT_LT(j["ate"]["aligned_se3"]["trans_m"]["rmse"].asDouble(), 0.04);
	EXPECT_LT(std::abs(j["vertical_drift"]["end_pct"].asDouble()), 0.05);
	EXPECT_LT(
	    j["return_to_start"]["estimate_vs_gt"]["total_trans_m"].asDouble(),
	    0.07);
	EXPECT_LT(j["return_to_start"]["estimate_vs_gt"]["angle_deg"].asDouble(),
	          0.3);

	// A forest walk is not a degenerate place.
	std::ifstream f(dir / "map" / "run_summary.json");
	Json::Value summary;
	Json::CharReaderBuilder b;
	std::string errs;
	ASSERT_TRUE(Json::parseFromStream(b, f, &summary, &errs)) << errs;
	EXPECT_LE(summary["scans_degenerate"].asUInt(), 3u);
	std::filesystem::remove_all(dir);
}
