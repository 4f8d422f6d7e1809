// Issue 12, sensor faults and degenerate places, end to end on the tiny
// forest-sim scenario: one fault-free baseline and one run with every fault
// of [faults] at a different time, one crossing an "open field" (ground
// returns only, a degenerate place). Each run goes through `forest-slam map`
// and `forest-eval traj`. Checked: the run finishes, the log names each
// fault exactly once with its time, the counters in run_summary.json see
// it, and the trajectory stays within 2x the fault-free ATE. On the same
// rawlog: SIGINT/SIGTERM mid-run (complete, valid outputs), kill -9 while
// the outputs are written (no half-written file under a final name) and
// reproducibility (the run after the kill is bit-identical to the first).
#include <forest_slam/io/las.h>
#include <forest_slam/io/tum.h>
#include <forest_slam/pipeline/mapping_job.h>
#include <gtest/gtest.h>

#include <json/json.h>
#include <sys/wait.h>
#include <unistd.h>
#include <algorithm>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "../online/process_helpers.h"

namespace fs = std::filesystem;

namespace
{
const std::string kBin = FOREST_SLAM_BIN_DIR, kSrc = FOREST_SLAM_SOURCE_DIR;

int run(const std::string& cmd)
{
	const int status = std::system(cmd.c_str());
	return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string slurp(const fs::path& p)
{
	std::ifstream f(p);
	std::stringstream ss;
	ss << f.rdbuf();
	return ss.str();
}

Json::Value readJson(const fs::path& p)
{
	std::ifstream f(p);
	Json::Value j;
	Json::CharReaderBuilder b;
	std::string errs;
	EXPECT_TRUE(Json::parseFromStream(b, f, &j, &errs)) << p << ": " << errs;
	return j;
}

/** forest-sim (sim-tiny + `faults`), forest-slam map, forest-eval traj in
 * dir/<name>; returns the aligned ATE RMSE [m]. */
struct MapRun
{
	fs::path dir;
	std::string log;
	Json::Value summary, traj;
	double ate_m = -1;
};

MapRun simulateAndMap(const fs::path& root, const std::string& name,
                      const std::string& faults)
{
	MapRun r;
	r.dir = root / name;
	fs::create_directories(r.dir);
	const std::string d = r.dir.string();
	{
		std::ofstream ini(r.dir / "sim.ini");
		ini << slurp(kSrc + "/ini/sim-tiny.ini") << "\n" << faults;
	}
	EXPECT_EQ(run(kBin + "/forest-sim --config " + d + "/sim.ini --seed 1 " +
	              "--out " + d + "/sim > " + d + "/sim.log 2>&1"),
	          0)
	    << "see " << d << "/sim.log";
	EXPECT_EQ(
	    run(kBin + "/forest-slam map --config " + kSrc +
	        "/ini/vlp16-handheld.ini --rawlog " + d + "/sim/run.rawlog --out " +
	        d + "/map > " + d + "/map.log 2>&1"),
	    0)
	    << "see " << d << "/map.log";
	EXPECT_EQ(run(kBin + "/forest-eval traj --gt " + d +
	              "/sim/gt_trajectory.tum --est " + d +
	              "/map/trajectory.tum --json " + d + "/traj.json > /dev/null"),
	          0);
	r.log = slurp(r.dir / "map.log");
	r.summary = readJson(r.dir / "map/run_summary.json");
	r.traj = readJson(r.dir / "traj.json");
	r.ate_m = r.traj["ate"]["aligned_se3"]["trans_m"]["rmse"].asDouble();
	return r;
}

/** Times (s into the run) of the log lines containing `what`: from
 * "(X s into the run)", else from "t=T" minus `t0` (the first scan). */
std::vector<double> faultTimes(const std::string& log, const std::string& what,
                               double t0 = 0)
{
	std::vector<double> out;
	std::istringstream is(log);
	const std::regex into(R"(\(([-0-9.]+) s into the run\))");
	const std::regex at(R"(t=([0-9.]+))");
	for (std::string line; std::getline(is, line);)
		if (line.find(what) != std::string::npos)
		{
			std::smatch m;
			if (std::regex_search(line, m, into))
				out.push_back(std::stod(m[1].str()));
			else if (std::regex_search(line, m, at))
				out.push_back(std::stod(m[1].str()) - t0);
			else
				out.push_back(-1e9);
		}
	return out;
}

class SimFaults : public ::testing::Test
{
   protected:
	static void SetUpTestSuite()
	{
		root_ = fs::temp_directory_path() /
		        ("fs_faults_" + std::to_string(::getpid()));
		fs::remove_all(root_);
		if (!fs::exists(kBin + "/forest-sim")) return;
		baseline_ = new MapRun(simulateAndMap(root_, "baseline", ""));
	}
	static void TearDownTestSuite()
	{
		delete baseline_;
		baseline_ = nullptr;
		// Kept for a look when something failed.
		if (::testing::UnitTest::GetInstance()->failed_test_count() == 0)
			fs::remove_all(root_);
	}
	void SetUp() override
	{
		if (!baseline_) GTEST_SKIP() << "forest-sim is not built";
	}
	static fs::path root_;
	static MapRun* baseline_;
};
fs::path SimFaults::root_;
MapRun* SimFaults::baseline_ = nullptr;

/** One fault: the log substring that names it, when it was injected, and
 * how long after that the pipeline may notice it (a gap is seen at its
 * end). */
struct Expected
{
	std::string log_text;
	double at_s, noticed_within_s;
	double early_s = 0.05;  ///< logged with a time this much before `at_s`
};

}  // namespace

TEST_F(SimFaults, EveryFaultNamedOnceAndTrajectoryHolds)
{
	const MapRun& base = *baseline_;
	ASSERT_GT(base.ate_m, 0);
	EXPECT_EQ(base.summary["scans_empty"].asUInt(), 0u);
	EXPECT_EQ(base.summary["lidar_gaps"].asUInt(), 0u);
	EXPECT_EQ(base.summary["imu_gaps"].asUInt(), 0u);
	EXPECT_EQ(base.summary["imu_rejected"].asUInt(), 0u);
	EXPECT_EQ(base.summary["gnss_rejected"].asUInt(), 0u);
	EXPECT_EQ(base.summary["points_nonfinite"].asUInt(), 0u);

	// sim-tiny: ~41 s; the walk starts after a 2 s pause.
	const MapRun f = simulateAndMap(root_, "faults",
	                                "[faults]\n"
	                                "nan_scan_at_s = 6\n"
	                                "empty_scan_at_s = 9\n"
	                                "lidar_gap_at_s = 12\n"
	                                "lidar_gap_s = 2\n"
	                                "imu_gap_at_s = 18\n"
	                                "imu_gap_s = 1\n"
	                                "imu_backwards_at_s = 22\n"
	                                "gnss_jump_at_s = 25\n"
	                                "gnss_jump_m = 50\n"
	                                "duplicate_scan_at_s = 31\n");
	const Expected expected[] = {
	    {"points not finite (NaN/inf)", 6, 0.2},
	    {"has no valid return", 9, 0.2},
	    {"lidar gap: no scan for", 12, 2.2},
	    {"IMU gap: no sample for", 18, 1.1},
	    // Logged with its own (backwards) stamp.
	    {"is not after the previous sample", 22, 0.1, 0.06},
	    {"repeats the previous scan's time (a duplicate)", 31, 0.2},
	};
	for (const auto& e : expected)
	{
		SCOPED_TRACE(e.log_text);
		const auto t = faultTimes(f.log, e.log_text);
		ASSERT_EQ(t.size(), 1u) << f.log;
		EXPECT_GE(t[0], e.at_s - e.early_s);
		EXPECT_LE(t[0], e.at_s + e.noticed_within_s);
	}
	// GNSS: the jump is named only if the receiver had a fix then.
	const auto& s = f.summary;
	const auto gnss_jump = faultTimes(f.log, "jumped");
	if (s["gnss"].asUInt() > 0 && s["gnss_rejected"].asUInt() > 0)
	{
		ASSERT_EQ(gnss_jump.size(), 1u) << f.log;
		EXPECT_GE(gnss_jump[0], 25 - 0.05);
		EXPECT_LE(gnss_jump[0], 25 + 5);
	}
	EXPECT_EQ(faultTimes(f.log, "GNSS fix at").size(), gnss_jump.size());

	EXPECT_EQ(s["scans_duplicate"].asUInt(), 1u);
	EXPECT_EQ(s["scans_empty"].asUInt(), 1u);
	EXPECT_EQ(s["scans_unreadable"].asUInt(), 1u);  // the all-NaN scan
	EXPECT_GT(s["points_nonfinite"].asUInt(), 10000u);
	EXPECT_EQ(s["lidar_gaps"].asUInt(), 1u);
	EXPECT_EQ(s["imu_gaps"].asUInt(), 1u);
	EXPECT_EQ(s["imu_rejected"].asUInt(), 1u);
	EXPECT_FALSE(s["input_damaged"].asBool());
	// Every scan not lost to a fault is mapped: the baseline's, minus the
	// 2 s gap (20 scans), the empty and the NaN one.
	EXPECT_EQ(s["scans_mapped"].asUInt(),
	          base.summary["scans_mapped"].asUInt() - 22u);

	// Issue 12: within 2x the fault-free ATE. Measured 0.0134 m against
	// 0.0105 m (1.3x); it was 0.049 m until the scans of the IMU gap got a
	// 5 deg rotation prior and their sweep's motion estimated (the IMU gap
	// alone: 0.064 m, now 0.012 m; doc/reliability.md). The runs are
	// bit-identical from run to run, so no allowance for noise.
	EXPECT_LE(f.ate_m, 2 * base.ate_m)
	    << "fault-free ATE " << base.ate_m << " m";
	std::printf("ATE: fault-free %.4f m, with faults %.4f m\n", base.ate_m,
	            f.ate_m);
}

TEST_F(SimFaults, OpenFieldIsDegenerateAndBridged)
{
	// 3 s with ground returns only, in the middle of the loop.
	const MapRun& base = *baseline_;
	const MapRun f = simulateAndMap(root_, "open_field",
	                                "[faults]\nopen_field_at_s = 14\n"
	                                "open_field_s = 3\n");
	// The log names the first degenerate scan of the run (the start, by the
	// parked vehicle, has a few); the window adds most of its 30 scans.
	EXPECT_EQ(faultTimes(f.log, "degenerate geometry").size(), 1u) << f.log;
	const auto& s = f.summary;
	EXPECT_GE(s["scans_degenerate"].asUInt(),
	          base.summary["scans_degenerate"].asUInt() + 15u);
	EXPECT_EQ(s["scans_mapped"].asUInt(),
	          base.summary["scans_mapped"].asUInt());
	// The motion model carries the pose through the 3 s (about 3.5 m
	// walked): without holding the weak directions on the prediction the
	// ATE was 0.83 m; holding them at constant velocity 0.031 m; at the mean
	// velocity of the last second before the stretch, with the
	// accelerometer deskew kept, 0.018 m (fault-free 0.0105 m: 1.7x; what
	// is left is the walker speeding up by 3 % in the field).
	EXPECT_LE(f.ate_m, 2 * base.ate_m)
	    << "fault-free ATE " << base.ate_m << " m";
	// The forest itself is never degenerate (the raw, unscaled information
	// flagged a third of the forest scans and held their translation on the
	// prediction, doc/reliability.md).
	EXPECT_LE(base.summary["scans_degenerate"].asUInt(), 2u);
	std::printf(
	    "ATE: fault-free %.4f m, open field %.4f m, %u degenerate "
	    "scans (fault-free %u)\n",
	    base.ate_m, f.ate_m, s["scans_degenerate"].asUInt(),
	    base.summary["scans_degenerate"].asUInt());
}

namespace
{
/** Every output a map run writes by default is complete and readable. */
void expectValidOutputs(const fs::path& out)
{
	const auto traj =
	    forest_slam::io::readTum((out / "trajectory.tum").string());
	EXPECT_GT(traj.size(), 0u);
	readJson(out / "run_summary.json");
	EXPECT_NO_THROW(forest_slam::io::readLas((out / "map.las").string()));
	EXPECT_NO_THROW(
	    forest_slam::pipeline::loadForestMap((out / "forest.map").string()));
	for (const auto& e : fs::directory_iterator(out))
		EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos)
		    << e.path();
}

std::vector<std::string> mapArgs(
    const fs::path& rawlog, const fs::path& out,
    const std::string& config = kSrc + "/ini/vlp16-handheld.ini")
{
	return {kBin + "/forest-slam", "map",   "--config",  config, "--rawlog",
	        rawlog.string(),       "--out", out.string()};
}

/** ini/vlp16-handheld.ini mapping only the first `scans` scans. */
std::string shortConfig(const fs::path& dir, int scans)
{
	std::string ini = slurp(kSrc + "/ini/vlp16-handheld.ini");
	const std::string key = "\nmax_scans = 0\n";
	const auto at = ini.find(key);
	EXPECT_NE(at, std::string::npos);
	ini.replace(at, key.size(),
	            "\nmax_scans = " + std::to_string(scans) + "\n");
	const auto path =
	    (dir / ("short" + std::to_string(scans) + ".ini")).string();
	std::ofstream(path) << ini;
	return path;
}
}  // namespace

TEST_F(SimFaults, SigintAndSigtermWriteCompleteOutputs)
{
	const uint64_t all = baseline_->summary["scans_mapped"].asUInt();
	for (const int sig : {SIGINT, SIGTERM})
	{
		SCOPED_TRACE(sig);
		const fs::path out = root_ / ("signal" + std::to_string(sig));
		online_test::Child c(
		    mapArgs(baseline_->dir / "sim/run.rawlog", out),
		    (root_ / ("signal" + std::to_string(sig) + ".log")).string());
		// Once mapping is under way (the first progress line or bar).
		ASSERT_TRUE(c.waitForOutput("mapping ", 60)) << c.output();
		std::this_thread::sleep_for(
		    std::chrono::milliseconds(sig == SIGINT ? 1500 : 3000));
		c.signal(sig);
		ASSERT_EQ(c.wait(300), 0) << c.output();
		EXPECT_NE(c.output().find("received: stopping, writing outputs"),
		          std::string::npos)
		    << c.output();
		expectValidOutputs(out);
		const auto s = readJson(out / "run_summary.json");
		EXPECT_TRUE(s["interrupted"].asBool());
		EXPECT_GT(s["scans_mapped"].asUInt(), 0u);
		EXPECT_LT(s["scans_mapped"].asUInt(), all);
		EXPECT_EQ(
		    forest_slam::io::readTum((out / "trajectory.tum").string()).size(),
		    s["scans_mapped"].asUInt());
	}
}

TEST_F(SimFaults, KillDashNineLeavesNoHalfFileAndRerunIsBitIdentical)
{
	// A complete run (the first 60 scans) in the folder; the same run again
	// killed while it writes its outputs: every final name holds a whole
	// file, the next run removes the dead run's temp files and gives
	// bit-identical results.
	const fs::path out = root_ / "killed", first = root_ / "first";
	constexpr int kScans = 60;
	const auto config = shortConfig(root_, kScans);
	{
		online_test::Child c(
		    mapArgs(baseline_->dir / "sim/run.rawlog", first, config),
		    (root_ / "first.log").string());
		ASSERT_EQ(c.wait(600), 0) << c.output();
	}
	fs::copy(first, out, fs::copy_options::recursive);
	int killed_mid_write = 0;
	for (int attempt = 0; attempt < 3 && killed_mid_write == 0; attempt++)
	{
		online_test::Child c(
		    mapArgs(baseline_->dir / "sim/run.rawlog", out, config),
		    (root_ / "killed.log").string());
		// Poll for a temp file, then SIGKILL at once.
		const auto end =
		    std::chrono::steady_clock::now() + std::chrono::seconds(600);
		bool seen = false;
		while (!seen && std::chrono::steady_clock::now() < end)
		{
			for (const auto& e : fs::directory_iterator(out))
				if (e.path().filename().string().find(".tmp.") !=
				    std::string::npos)
					seen = true;
			if (!seen)
				std::this_thread::sleep_for(std::chrono::microseconds(500));
		}
		ASSERT_TRUE(seen);
		c.signal(SIGKILL);
		EXPECT_EQ(c.wait(60), -1);
		size_t temps = 0;
		for (const auto& e : fs::directory_iterator(out))
			temps +=
			    e.path().filename().string().find(".tmp.") != std::string::npos;
		killed_mid_write += temps > 0;
		// The final names: whole files.
		const auto traj =
		    forest_slam::io::readTum((out / "trajectory.tum").string());
		EXPECT_EQ(traj.size(), size_t(kScans));
		readJson(out / "run_summary.json");
		EXPECT_NO_THROW(forest_slam::io::readLas((out / "map.las").string()));
		EXPECT_NO_THROW(forest_slam::pipeline::loadForestMap(
		    (out / "forest.map").string()));
	}
	EXPECT_GT(killed_mid_write, 0) << "never caught a temp file on disk";
	// The next run cleans up and completes.
	online_test::Child c(
	    mapArgs(baseline_->dir / "sim/run.rawlog", out, config),
	    (root_ / "after_kill.log").string());
	ASSERT_EQ(c.wait(600), 0) << c.output();
	EXPECT_NE(c.output().find("left by a run killed while writing it"),
	          std::string::npos)
	    << c.output();
	expectValidOutputs(out);
	// Same input, same configuration: bit-identical results.
	for (const char* f : {"trajectory.tum", "trajectory.kitti", "trees.csv"})
		EXPECT_EQ(slurp(out / f), slurp(first / f)) << f;
}
