#include <forest_slam/eval/tree_metrics.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

using namespace forest_slam;
using namespace forest_slam::eval;

namespace
{
TreeRecord tree(const std::string& id, double x, double y, double dbh,
                bool sapling = false)
{
	TreeRecord t;
	t.id = id;
	t.x = x;
	t.y = y;
	t.dbh_m = dbh;
	t.sapling = sapling;
	return t;
}

core::Trajectory lineTraj(double x0, double x1)
{
	core::Trajectory t(2);
	t[0].t_s = 0;
	t[0].pose.translation() = Eigen::Vector3d(x0, 0, 0);
	t[1].t_s = 1;
	t[1].pose.translation() = Eigen::Vector3d(x1, 0, 0);
	return t;
}

std::string writeTemp(const std::string& name, const std::string& content)
{
	const auto dir = std::filesystem::temp_directory_path() /
	                 ("forest_eval_trees_" + std::to_string(::getpid()));
	std::filesystem::create_directories(dir);
	const auto p = (dir / name).string();
	std::ofstream(p) << content;
	return p;
}

std::string errorOf(const std::function<void()>& f)
{
	try
	{
		f();
	}
	catch (const std::exception& e)
	{
		return e.what();
	}
	return "";
}

// Six GT trees and six estimates covering every status (see each comment).
std::vector<TreeRecord> scenarioGt()
{
	return {tree("g0", 0, 0, 0.30),        // matched by e0
	        tree("g1", 5, 0, 0.40),        // matched by e1
	        tree("g2", 10, 0, 0.25),       // missed
	        tree("g3", 0, 5, 0.08),        // below 10 cm, estimated by e2
	        tree("g4", 5, 5, 0.05, true),  // sapling
	        tree("g5", 100, 0, 0.50)};     // 90 m from the trajectory
}

std::vector<TreeRecord> scenarioEst()
{
	return {tree("e0", 0.1, 0, 0.32),   tree("e1", 5, 0.2, 0.36),
	        tree("e2", 0, 5.1, 0.09),   tree("e3", 3, 3, 0.20),
	        tree("e4", 100, 0.1, 0.45), tree("e5", 60, 0, 0.30)};
}
}  // namespace

TEST(DbhErrors, PaperFormulasByHand)
{
	// x - y = +0.02, -0.02, +0.01
	const auto e = dbhErrors({0.22, 0.30, 0.41}, {0.20, 0.32, 0.40});
	EXPECT_EQ(e.count, 3u);
	EXPECT_NEAR(e.rmse_m, std::sqrt(3e-4), 1e-12);  // sqrt(9e-4 / 3)
	EXPECT_NEAR(e.mae_m, 0.05 / 3, 1e-12);
	EXPECT_NEAR(e.mape_pct, 6.25, 1e-9);  // (10 + 6.25 + 2.5) % / 3
	EXPECT_NEAR(e.bias_m, 0.01 / 3, 1e-12);
	EXPECT_NEAR(e.rel_rmse_pct, 100 * std::sqrt(3e-4) / (0.92 / 3), 1e-9);
	EXPECT_NEAR(e.rel_bias_pct, 100 * (0.01 / 3) / (0.92 / 3), 1e-9);

	EXPECT_TRUE(std::isnan(dbhErrors({0.1}, {0.0}).mape_pct));
	EXPECT_EQ(dbhErrors({}, {}).count, 0u);
	EXPECT_TRUE(std::isnan(dbhErrors({}, {}).rmse_m));
	EXPECT_THROW(dbhErrors({0.1}, {}), std::invalid_argument);
}

TEST(DetectionScores, ByHand)
{
	double r, p, f;
	detectionScores(93, 2, 1, r, p, f);
	EXPECT_NEAR(r, 93.0 / 95, 1e-12);
	EXPECT_NEAR(p, 93.0 / 94, 1e-12);
	EXPECT_NEAR(f, 2 * 93.0 / (2 * 93 + 2 + 1), 1e-12);  // 2TP/(2TP+FN+FP)
	detectionScores(0, 3, 2, r, p, f);
	EXPECT_EQ(f, 0.0);
	detectionScores(0, 0, 2, r, p, f);
	EXPECT_TRUE(std::isnan(r));
	EXPECT_EQ(p, 0.0);
}

TEST(EvaluateTrees, EveryStatusWithRange)
{
	TreeEvalOptions o;
	o.max_range_m = 15;
	const auto gt = scenarioGt();
	const auto est = scenarioEst();
	const Region west{"west", -1, -1, 6, 6}, east{"east", 6, -1, 20, 6};
	const auto ev = evaluateTrees(gt, est, o, lineTraj(0, 10), {west, east});

	EXPECT_EQ(ev.gt_evaluated, 3u);
	EXPECT_EQ(ev.gt_below_min_dbh, 1u);
	EXPECT_EQ(ev.gt_sapling, 1u);
	EXPECT_EQ(ev.gt_out_of_range, 1u);
	EXPECT_EQ(ev.tp, 2u);
	EXPECT_EQ(ev.fn, 1u);
	EXPECT_EQ(ev.fp, 1u);
	EXPECT_EQ(ev.est_matched_excluded, 2u);  // e2 (small tree), e4 (far tree)
	EXPECT_EQ(ev.est_out_of_range, 1u);      // e5
	EXPECT_EQ(ev.est_status[3], EstTreeStatus::FalsePositive);
	EXPECT_EQ(ev.est_status[5], EstTreeStatus::OutOfRange);
	EXPECT_NEAR(ev.recall, 2.0 / 3, 1e-12);
	EXPECT_NEAR(ev.precision, 2.0 / 3, 1e-12);
	EXPECT_NEAR(ev.f1, 2.0 / 3, 1e-12);
	// Position errors 0.1 and 0.2 m.
	EXPECT_NEAR(ev.position_err_m.rmse, std::sqrt(0.025), 1e-12);
	// DBH: x = .32, .36; y = .30, .40.
	EXPECT_NEAR(ev.dbh.rmse_m, std::sqrt(1e-3), 1e-12);
	EXPECT_NEAR(ev.dbh.mae_m, 0.03, 1e-12);
	EXPECT_NEAR(ev.dbh.mape_pct, 100 * (1.0 / 15 + 0.1) / 2, 1e-9);
	EXPECT_NEAR(ev.dbh.bias_m, -0.01, 1e-12);

	ASSERT_EQ(ev.regions.size(), 2u);
	const auto& w = ev.regions[0];
	EXPECT_EQ(w.measured_count, 2u);
	EXPECT_NEAR(w.measured_dbh_m.mean, 0.35, 1e-12);
	EXPECT_NEAR(w.measured_dbh_m.std, std::sqrt(0.005), 1e-12);
	EXPECT_NEAR(w.measured_dbh_m.min, 0.30, 1e-12);
	EXPECT_NEAR(w.measured_dbh_m.max, 0.40, 1e-12);
	EXPECT_EQ(w.estimated_count, 3u);  // e0, e1 and the false positive e3
	EXPECT_NEAR(w.estimated_dbh_m.mean, 0.88 / 3,
	            1e-12);  // (.32 + .36 + .20) / 3
	EXPECT_NEAR(w.estimated_dbh_m.min, 0.20, 1e-12);
	EXPECT_NEAR(w.estimated_dbh_m.max, 0.36, 1e-12);
	EXPECT_EQ(w.tp, 2u);
	EXPECT_EQ(w.fp, 1u);
	EXPECT_DOUBLE_EQ(w.recall, 1.0);
	EXPECT_NEAR(w.precision, 2.0 / 3, 1e-12);
	EXPECT_NEAR(w.dbh.rmse_m, std::sqrt(1e-3), 1e-12);
	const auto& e = ev.regions[1];
	EXPECT_EQ(e.measured_count, 1u);
	EXPECT_EQ(e.estimated_count, 0u);
	EXPECT_EQ(e.fn, 1u);
	EXPECT_DOUBLE_EQ(e.recall, 0.0);
	EXPECT_TRUE(std::isnan(e.precision));
	EXPECT_EQ(e.dbh.count, 0u);
}

TEST(EvaluateTrees, WithoutRangeAndThresholds)
{
	const auto gt = scenarioGt();
	const auto est = scenarioEst();
	TreeEvalOptions o;
	const auto ev = evaluateTrees(gt, est, o);  // no trajectory: no range rule
	EXPECT_EQ(ev.gt_evaluated, 4u);             // g5 now counts
	EXPECT_EQ(ev.tp, 3u);                       // e4 matches g5
	EXPECT_EQ(ev.fp, 2u);                       // e3 and e5
	ASSERT_EQ(ev.regions.size(), 1u);
	EXPECT_EQ(ev.regions[0].region.name, "all");
	EXPECT_EQ(ev.regions[0].measured_count, 4u);

	o.min_dbh_m = 0.05;  // g3 (8 cm) now evaluated, e2 is its true positive
	EXPECT_EQ(evaluateTrees(gt, est, o).tp, 4u);
	o.max_match_m = 0.05;  // only exact-ish positions match: none here
	EXPECT_EQ(evaluateTrees(gt, est, o).tp, 0u);
}

TEST(PositionErrorStructure, SeparatesOffsetScaleAndNoise)
{
	// A map 0.07 % short about its origin, turned by 0.01 deg, shifted by
	// (2, -1) cm, with 1 cm of noise per axis on each tree.
	std::mt19937 rng(7);
	std::uniform_real_distribution<double> u(-80, 80);
	std::normal_distribution<double> noise(0, 0.01);
	const double s = 1 - 7e-4, a = 0.01 * M_PI / 180;
	const Eigen::Matrix2d R = Eigen::Rotation2Dd(a).toRotationMatrix();
	std::vector<Eigen::Vector2d> gt, est, est_exact;
	for (int i = 0; i < 400; i++)
	{
		const Eigen::Vector2d g(u(rng), u(rng));
		const Eigen::Vector2d e = s * R * g + Eigen::Vector2d(0.02, -0.01);
		gt.push_back(g);
		est_exact.push_back(e);
		est.push_back(e + Eigen::Vector2d(noise(rng), noise(rng)));
	}
	const auto exact = positionErrorStructure(gt, est_exact);
	EXPECT_NEAR(exact.scale, s, 1e-9);
	EXPECT_NEAR(exact.rotation_deg, 0.01, 1e-7);
	EXPECT_NEAR(exact.rmse_after_similarity_m, 0, 1e-9);
	// The mean offset is the shift plus the scale's mean displacement.
	double mx = 0, my = 0;
	for (size_t i = 0; i < gt.size(); i++)
		mx += est_exact[i].x() - gt[i].x(), my += est_exact[i].y() - gt[i].y();
	EXPECT_NEAR(exact.offset_x_m, mx / gt.size(), 1e-12);
	EXPECT_NEAR(exact.offset_y_m, my / gt.size(), 1e-12);

	const auto noisy = positionErrorStructure(gt, est);
	EXPECT_EQ(noisy.count, 400u);
	EXPECT_NEAR(noisy.scale, s, 1e-4);
	// What is left is the noise: sqrt(2) cm.
	EXPECT_NEAR(noisy.rmse_after_similarity_m, std::sqrt(2.0) * 0.01, 0.001);
	// The scale alone spreads the trees by up to 8 cm: an offset does not
	// take it away.
	EXPECT_GT(noisy.rmse_after_offset_m, 0.03);

	// Too few pairs: no fit; unequal lists: an error.
	EXPECT_TRUE(std::isnan(
	    positionErrorStructure({gt[0], gt[1]}, {est[0], est[1]}).scale));
	EXPECT_THROW(positionErrorStructure(gt, {est[0]}), std::invalid_argument);
}

TEST(TrajectoryCorridor, MatchesBruteForce)
{
	core::Trajectory t;
	std::mt19937 rng(7);
	std::uniform_real_distribution<double> step(-3, 3);
	Eigen::Vector3d p(0, 0, 0);
	for (int i = 0; i < 300; i++)
	{
		core::StampedPose s;
		s.t_s = i;
		// Every 50th step is a 60 m jump: long segments must be found too.
		p += i % 50 == 49 ? Eigen::Vector3d(60, 20, 0)
		                  : Eigen::Vector3d(step(rng), step(rng), 0);
		s.pose.translation() = p;
		t.push_back(s);
	}
	const TrajectoryCorridor c(t, 15);
	std::uniform_real_distribution<double> q(-50, 400);
	for (int k = 0; k < 2000; k++)
	{
		const Eigen::Vector2d x(q(rng), q(rng));
		double best = 1e300;
		for (size_t i = 1; i < t.size(); i++)
		{
			const Eigen::Vector2d a = t[i - 1].pose.translation().head<2>();
			const Eigen::Vector2d b = t[i].pose.translation().head<2>();
			const double u = std::clamp(
			    (x - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
			best = std::min(best, (a + u * (b - a) - x).norm());
		}
		ASSERT_NEAR(c.distance(x.x(), x.y()), best, 1e-9);
		ASSERT_EQ(c.within(x.x(), x.y()), best <= 15);
	}
	const TrajectoryCorridor single(lineTraj(2, 2), 5);
	EXPECT_NEAR(single.distance(5, 4), 5.0, 1e-12);
}

TEST(TreeFiles, ReadAndErrors)
{
	const auto gt =
	    writeTemp("gt.csv",
	              "id,x,y,z_ground,dbh_m,height_m,lean_deg,sapling\n"
	              "1,1.5,2.5,0.1,0.31,22,1.5,0\n"
	              "2,3,4,0.2,0.04,3,0,1\n");
	const auto g = readTreesCsv(gt);
	ASSERT_EQ(g.size(), 2u);
	EXPECT_EQ(g[0].id, "1");
	EXPECT_DOUBLE_EQ(g[0].dbh_m, 0.31);
	EXPECT_FALSE(g[0].sapling);
	EXPECT_TRUE(g[1].sapling);
	EXPECT_EQ(g[1].line, 3u);

	const auto est =
	    writeTemp("est.csv", "x,y,id,dbh_m,score\n1,2,a,0.3,0.9\n");
	EXPECT_EQ(readTreesCsv(est)[0].id, "a");

	const auto neg =
	    writeTemp("neg.csv", "id,x,y,dbh_m\n1,0,0,0.2\n2,0,0,-0.1\n");
	EXPECT_NE(errorOf([&] { readTreesCsv(neg); })
	              .find(neg + ":3:4 (dbh_m): expected a DBH >= 0"),
	          std::string::npos);
	const auto nodbh = writeTemp("nodbh.csv", "id,x,y,dbh_cm\n");
	EXPECT_NE(errorOf([&] { readTreesCsv(nodbh); }).find("no column 'dbh_m'"),
	          std::string::npos);
	const auto sap =
	    writeTemp("sap.csv", "id,x,y,dbh_m,sapling\n1,0,0,0.2,maybe\n");
	EXPECT_NE(errorOf([&] { readTreesCsv(sap); }).find(sap + ":2:5 (sapling)"),
	          std::string::npos);

	const auto reg = writeTemp(
	    "reg.csv", "name,xmin,ymin,xmax,ymax\nA,0,0,10,10\nB,10,0,20,10\n");
	const auto r = readRegionsCsv(reg);
	ASSERT_EQ(r.size(), 2u);
	EXPECT_TRUE(r[1].contains(10, 5));
	EXPECT_FALSE(r[1].contains(9.99, 5));
	const auto inv =
	    writeTemp("inv.csv", "name,xmin,ymin,xmax,ymax\nA,5,0,1,10\n");
	EXPECT_NE(errorOf([&] { readRegionsCsv(inv); })
	              .find(inv + ":2:4 (xmax): expected xmax >= xmin"),
	          std::string::npos);
	const auto dup = writeTemp(
	    "dupreg.csv", "name,xmin,ymin,xmax,ymax\nA,0,0,1,1\nA,0,0,1,1\n");
	EXPECT_NE(errorOf([&] { readRegionsCsv(dup); }).find("defined twice"),
	          std::string::npos);
}
