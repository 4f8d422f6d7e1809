// End to end: forest-eval on small files written here; the JSON is read back
// with jsoncpp (an independent parser) and checked against hand numbers.
#include <forest_slam/io/tum.h>
#include <gtest/gtest.h>
#include <json/json.h>

#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

using namespace forest_slam;
namespace fs = std::filesystem;

namespace
{
struct RunResult
{
	int code = -1;
	std::string out, err;
};

class ForestEvalApp : public ::testing::Test
{
   protected:
	void SetUp() override
	{
		dir_ =
		    fs::temp_directory_path() /
		    ("forest_eval_app_" + std::to_string(::getpid()) + "_" +
		     ::testing::UnitTest::GetInstance()->current_test_info()->name());
		fs::remove_all(dir_);
		fs::create_directories(dir_);
	}
	void TearDown() override
	{
		if (!HasFailure() && !std::getenv("FOREST_EVAL_KEEP"))
			fs::remove_all(dir_);
	}

	std::string path(const std::string& name) const
	{
		return (dir_ / name).string();
	}

	std::string write(const std::string& name, const std::string& content) const
	{
		std::ofstream(path(name)) << content;
		return path(name);
	}

	RunResult run(const std::string& args) const
	{
		const std::string cmd = std::string(FOREST_SLAM_BIN_DIR) +
		                        "/forest-eval " + args + " >" +
		                        path("stdout.txt") + " 2>" + path("stderr.txt");
		const int status = std::system(cmd.c_str());
		RunResult r;
		r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
		r.out = slurp(path("stdout.txt"));
		r.err = slurp(path("stderr.txt"));
		return r;
	}

	static std::string slurp(const std::string& p)
	{
		std::ifstream f(p);
		std::stringstream ss;
		ss << f.rdbuf();
		return ss.str();
	}

	static Json::Value readJson(const std::string& p)
	{
		std::ifstream f(p);
		Json::Value v;
		Json::CharReaderBuilder b;
		std::string errs;
		EXPECT_TRUE(Json::parseFromStream(b, f, &v, &errs))
		    << p << ": " << errs;
		return v;
	}

	fs::path dir_;
};

constexpr double kT0 = 1700000000.0;

/** 40 m x 20 m rectangle at 1 m/s, 10 Hz, back exactly at the start pose. */
core::Trajectory rectangleGt()
{
	core::Trajectory t;
	for (int k = 0; k <= 1200; k++)
	{
		const double s = 0.1 * k;
		double x, y, yaw;
		if (s <= 40)
			x = s, y = 0, yaw = 0;
		else if (s <= 60)
			x = 40, y = s - 40, yaw = M_PI / 2;
		else if (s <= 100)
			x = 100 - s, y = 20, yaw = M_PI;
		else
			x = 0, y = 120 - s, yaw = -M_PI / 2;
		core::StampedPose p;
		p.t_s = kT0 + s;
		p.pose.linear() =
		    Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
		p.pose.translation() = Eigen::Vector3d(x, y, 0);
		t.push_back(p);
	}
	// Turn in place back to the start heading over 2 s, as the operator
	// does at the end of a return-to-start run.
	for (int k = 1; k <= 20; k++)
	{
		core::StampedPose p = t.back();
		p.t_s = kT0 + 120 + 0.1 * k;
		p.pose.linear() = Eigen::AngleAxisd(-M_PI / 2 * (1 - k / 20.0),
		                                    Eigen::Vector3d::UnitZ())
		                      .toRotationMatrix();
		t.push_back(p);
	}
	return t;
}

/** Estimate = GT shifted by (0.3, -0.4, 0), climbing 1 cm per metre over
 * the last 20 m (so it ends 0.2 m high). */
core::Trajectory rectangleEst(const core::Trajectory& gt)
{
	auto est = gt;
	for (auto& p : est)
	{
		const double s = p.t_s - kT0;
		p.pose.translation() +=
		    Eigen::Vector3d(0.3, -0.4, 0.01 * std::clamp(s - 100, 0.0, 20.0));
	}
	return est;
}
}  // namespace

TEST_F(ForestEvalApp, TrajEndToEnd)
{
	const auto gt = rectangleGt();
	io::writeTum(path("gt.tum"), gt);
	io::writeTum(path("est.tum"), rectangleEst(gt));
	// GNSS at 1 Hz in the map frame, 3 m above the GT.
	std::ostringstream g;
	g.precision(12);
	g << "t,x,y,z,fix\n";
	for (size_t k = 0; k < gt.size(); k += 10)
	{
		const auto& p = gt[k].pose.translation();
		g << gt[k].t_s << "," << p.x() << "," << p.y() << "," << p.z() + 3
		  << ",4\n";
	}
	write("gnss.csv", g.str());

	const auto r =
	    run("traj --gt " + path("gt.tum") + " --est " + path("est.tum") +
	        " --gnss " + path("gnss.csv") + " --json " + path("out.json") +
	        " --svg " + path("out.svg"));
	ASSERT_EQ(r.code, 0) << r.err;
	EXPECT_NE(r.out.find("Return to start"), std::string::npos) << r.out;
	EXPECT_NE(r.out.find("Drift against GNSS"), std::string::npos);

	const auto j = readJson(path("out.json"));
	EXPECT_EQ(j["command"].asString(), "traj");
	EXPECT_EQ(j["association"]["pairs"].asInt(), 1221);
	EXPECT_NEAR(j["association"]["gt_path_length_m"].asDouble(), 120.0, 1e-6);
	// Offset 0.5 m everywhere plus the final climb: the unaligned ATE is at
	// least 0.5 m, and the closure error is the 0.2 m climb alone.
	EXPECT_GE(j["ate"]["unaligned"]["trans_m"]["min"].asDouble(), 0.5 - 1e-6);
	EXPECT_LT(j["ate"]["aligned_se3"]["trans_m"]["rmse"].asDouble(),
	          j["ate"]["unaligned"]["trans_m"]["rmse"].asDouble());
	const auto& rts = j["return_to_start"]["estimate"];
	EXPECT_NEAR(rts["z_m"].asDouble(), 0.2, 1e-5);
	EXPECT_NEAR(rts["x_m"].asDouble(), 0.0, 1e-5);
	EXPECT_NEAR(rts["total_trans_m"].asDouble(), 0.2, 1e-5);
	EXPECT_NEAR(rts["total_rot_deg"].asDouble(), 0.0, 1e-4);
	EXPECT_NEAR(j["return_to_start"]["gt"]["total_trans_m"].asDouble(), 0.0,
	            1e-5);
	EXPECT_NEAR(j["vertical_drift"]["end_abs_err_m"].asDouble(), 0.2, 1e-5);
	EXPECT_NEAR(j["vertical_drift"]["end_pct"].asDouble(), 0.2 / 120 * 100,
	            1e-4);
	// The climb is the only relative error: segments not touching the last
	// 20 m have none, so the average is small but not zero.
	EXPECT_GT(j["rpe"]["segments"].asInt(), 0);
	EXPECT_GT(j["rpe"]["trans_err_pct"].asDouble(), 0.0);
	EXPECT_LT(j["rpe"]["trans_err_pct"].asDouble(), 1.0);
	// GNSS every 10 s: t = 0 .. 120 -> 13 samples, 0.5 m horizontally.
	const auto& gd = j["gnss_drift"];
	EXPECT_EQ(gd["samples"].asInt(), 13);
	EXPECT_EQ(gd["skipped_no_fix"].asInt(), 0);
	EXPECT_NEAR(gd["dist_2d_m"]["mean"].asDouble(), 0.5, 1e-5);
	EXPECT_NEAR(gd["dist_2d_m"]["std"].asDouble(), 0.0, 1e-5);
	EXPECT_NEAR(gd["dist_3d_m"]["min"].asDouble(), std::sqrt(0.25 + 2.8 * 2.8),
	            1e-5);
	EXPECT_NEAR(gd["dist_3d_m"]["max"].asDouble(), std::sqrt(0.25 + 9), 1e-5);

	const std::string svg = slurp(path("out.svg"));
	EXPECT_EQ(svg.rfind("<?xml", 0), 0u);
	EXPECT_NE(svg.find("<polyline"), std::string::npos);
	EXPECT_NE(svg.find("</svg>"), std::string::npos);
}

TEST_F(ForestEvalApp, TrajWithoutGtGivesReturnToStartOnly)
{
	io::writeTum(path("est.tum"), rectangleEst(rectangleGt()));
	const auto r =
	    run("traj --est " + path("est.tum") + " --json=" + path("o.json"));
	ASSERT_EQ(r.code, 0) << r.err;
	const auto j = readJson(path("o.json"));
	EXPECT_TRUE(j["ate"].isNull());
	EXPECT_NEAR(j["return_to_start"]["estimate"]["z_m"].asDouble(), 0.2, 1e-5);
}

TEST_F(ForestEvalApp, TreesEndToEnd)
{
	write("gt.csv",
	      "id,x,y,z_ground,dbh_m,height_m,lean_deg,sapling\n"
	      "g0,0,0,0,0.30,20,1,0\n"
	      "g1,5,0,0,0.40,22,0,0\n"
	      "g2,10,0,0,0.25,18,2,0\n"
	      "g3,0,5,0,0.08,6,0,0\n"
	      "g4,5,5,0,0.05,2,0,1\n"
	      "g5,100,0,0,0.50,25,0,0\n");
	write("est.csv",
	      "id,x,y,dbh_m,points\n"
	      "e0,0.1,0,0.32,400\n"
	      "e1,5,0.2,0.36,380\n"
	      "e2,0,5.1,0.09,150\n"
	      "e3,3,3,0.20,120\n"
	      "e4,100,0.1,0.45,300\n"
	      "e5,60,0,0.30,200\n");
	write("traj.tum", "1 0 0 0 0 0 0 1\n2 10 0 0 0 0 0 1\n");
	write("regions.csv",
	      "name,xmin,ymin,xmax,ymax\nwest,-1,-1,6,6\neast,6,-1,20,6\n");
	const auto r = run("trees --gt " + path("gt.csv") + " --est " +
	                   path("est.csv") + " --max-range-m 15 --traj " +
	                   path("traj.tum") + " --regions " + path("regions.csv") +
	                   " --json " + path("t.json") + " --svg " + path("t.svg"));
	ASSERT_EQ(r.code, 0) << r.err;
	EXPECT_NE(r.out.find("west"), std::string::npos) << r.out;
	const auto j = readJson(path("t.json"));
	EXPECT_EQ(j["detection"]["tp"].asInt(), 2);
	EXPECT_EQ(j["detection"]["fn"].asInt(), 1);
	EXPECT_EQ(j["detection"]["fp"].asInt(), 1);
	EXPECT_NEAR(j["detection"]["recall"].asDouble(), 2.0 / 3, 1e-9);
	EXPECT_NEAR(j["dbh"]["rmse_m"].asDouble(), std::sqrt(1e-3), 1e-9);
	EXPECT_NEAR(j["dbh"]["mae_m"].asDouble(), 0.03, 1e-9);
	EXPECT_NEAR(j["dbh"]["mape_pct"].asDouble(), 100 * (1.0 / 15 + 0.1) / 2,
	            1e-9);
	EXPECT_NEAR(j["dbh"]["bias_m"].asDouble(), -0.01, 1e-9);
	EXPECT_NEAR(j["position_err_m"]["rmse"].asDouble(), std::sqrt(0.025), 1e-9);
	EXPECT_EQ(j["gt"]["out_of_range"].asInt(), 1);
	EXPECT_EQ(j["est"]["matched_excluded"].asInt(), 2);
	ASSERT_EQ(j["regions"].size(), 2u);
	EXPECT_EQ(j["regions"][0]["name"].asString(), "west");
	EXPECT_EQ(j["regions"][0]["measured"]["count"].asInt(), 2);
	EXPECT_NEAR(j["regions"][0]["measured"]["avg_m"].asDouble(), 0.35, 1e-9);
	EXPECT_EQ(j["regions"][0]["estimated"]["count"].asInt(), 3);
	EXPECT_EQ(j["missed_gt_ids"][0].asString(), "g2");
	EXPECT_EQ(j["false_positive_est_ids"][0].asString(), "e3");
	const std::string svg = slurp(path("t.svg"));
	EXPECT_NE(svg.find("1:1"), std::string::npos);
	EXPECT_NE(svg.find("</svg>"), std::string::npos);

	// Defaults: one region "all", no range rule.
	const auto d = run("trees --gt " + path("gt.csv") + " --est " +
	                   path("est.csv") + " --json " + path("d.json"));
	ASSERT_EQ(d.code, 0) << d.err;
	const auto jd = readJson(path("d.json"));
	EXPECT_EQ(jd["regions"][0]["name"].asString(), "all");
	EXPECT_TRUE(jd["regions"][0]["xmin"].isNull());
	EXPECT_EQ(jd["detection"]["tp"].asInt(), 3);
}

TEST_F(ForestEvalApp, UsageErrorsExitTwo)
{
	write("a.tum", "0 0 0 0 0 0 0 1\n");
	EXPECT_EQ(run("").code, 2);
	EXPECT_EQ(run("frobnicate").code, 2);
	auto r = run("traj --est " + path("a.tum") + " --bogus 1");
	EXPECT_EQ(r.code, 2);
	EXPECT_NE(r.err.find("unknown option '--bogus'"), std::string::npos)
	    << r.err;
	EXPECT_EQ(run("traj --gt " + path("a.tum")).code, 2);  // --est missing
	EXPECT_EQ(run("traj --est " + path("a.tum") + " --max-gap-s abc").code, 2);
	EXPECT_EQ(
	    run("traj --est " + path("a.tum") + " --rpe-lengths-m 10,,20").code, 2);
	EXPECT_EQ(
	    run("traj --est " + path("a.tum") + " --est " + path("a.tum")).code, 2);
	EXPECT_EQ(run("traj --est").code, 2);
	EXPECT_EQ(run("trees --gt g.csv --est e.csv --max-range-m 15").code, 2);
	EXPECT_EQ(run("trees --gt g.csv --est e.csv --max-match-m -1").code, 2);
	EXPECT_EQ(run("trees --gt g.csv stray").code, 2);

	r = run("--help");
	EXPECT_EQ(r.code, 0);
	EXPECT_NE(r.out.find("Usage: forest-eval <command>"), std::string::npos);
	r = run("traj --help");
	EXPECT_EQ(r.code, 0);
	EXPECT_NE(r.out.find("--gnss-interval-s"), std::string::npos);
	r = run("trees -h");
	EXPECT_EQ(r.code, 0);
	EXPECT_NE(r.out.find("--max-match-m"), std::string::npos);
}

TEST_F(ForestEvalApp, RuntimeErrorsExitOneAndNameTheFile)
{
	write("gt.tum", "0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n");
	write("bad.tum", "# header\n0 0 0 0 0 0 0 1\n1 1 0 zero 0 0 0 1\n");
	auto r = run("traj --gt " + path("gt.tum") + " --est " + path("bad.tum") +
	             " --json " + path("o.json"));
	EXPECT_EQ(r.code, 1);
	EXPECT_NE(r.err.find(path("bad.tum") + ":3:"), std::string::npos) << r.err;
	EXPECT_FALSE(fs::exists(path("o.json")));

	write("late.tum", "50 0 0 0 0 0 0 1\n51 1 0 0 0 0 0 1\n");
	r = run("traj --gt " + path("gt.tum") + " --est " + path("late.tum"));
	EXPECT_EQ(r.code, 1);
	EXPECT_NE(r.err.find("do not overlap in time"), std::string::npos) << r.err;

	write("gnss.csv", "t,x,y,z\n100,0,0,0\n");
	r = run("traj --est " + path("gt.tum") + " --gnss " + path("gnss.csv"));
	EXPECT_EQ(r.code, 1);
	EXPECT_NE(r.err.find("do not overlap in time"), std::string::npos) << r.err;

	r = run("traj --est " + path("missing.tum"));
	EXPECT_EQ(r.code, 1);
	EXPECT_NE(r.err.find("missing.tum"), std::string::npos);

	write("trees.csv", "id,x,y,dbh_m\n1,0,0,0.3\n2,0,1,0..3\n");
	r = run("trees --gt " + path("trees.csv") + " --est " + path("trees.csv"));
	EXPECT_EQ(r.code, 1);
	EXPECT_NE(r.err.find(path("trees.csv") + ":3:4 (dbh_m)"), std::string::npos)
	    << r.err;

	write("ok.csv", "id,x,y,dbh_m\n1,0,0,0.3\n");
	r = run("trees --gt " + path("ok.csv") + " --est " + path("ok.csv") +
	        " --json " + path("no/such/dir/o.json"));
	EXPECT_EQ(r.code, 1);
	EXPECT_NE(r.err.find("no/such/dir/o.json"), std::string::npos) << r.err;
}
