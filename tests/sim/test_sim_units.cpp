// Unit tests of the simulator's parts: strict configuration, the C2 motion
// spline and its derivatives, ray/primitive intersections, terrain and grid
// ray casting against brute force, and the planned motions.
#include <forest_slam/core/config.h>
#include <forest_slam/core/scan_points.h>
#include <forest_slam/sim/body_trajectory.h>
#include <forest_slam/sim/lidar_sim.h>
#include <forest_slam/sim/motion_planner.h>
#include <forest_slam/sim/options.h>
#include <forest_slam/sim/random.h>
#include <forest_slam/sim/simulator.h>
#include <forest_slam/sim/terrain.h>
#include <forest_slam/sim/world.h>
#include <gtest/gtest.h>

#include <cmath>
#include <mrpt/core/Clock.h>

using namespace forest_slam;
using namespace forest_slam::sim;

namespace
{
/** Expects loadText to throw ConfigError whose message contains all of
 * `parts`. */
void expectConfigError(const std::string& ini,
                       const std::vector<std::string>& parts)
{
	try
	{
		SimOptions::loadText(ini, "my.ini");
		FAIL() << "no error for:\n" << ini;
	}
	catch (const core::ConfigError& e)
	{
		const std::string msg = e.what();
		for (const auto& p : parts)
			EXPECT_NE(msg.find(p), std::string::npos)
			    << "'" << p << "' not in: " << msg;
	}
}

Eigen::Vector3d rotationLog(const Eigen::Matrix3d& R)
{
	const Eigen::AngleAxisd aa(R);
	return aa.angle() * aa.axis();
}

World flatWorld(double roughness = 0.0)
{
	TerrainOptions to;
	to.elevation_range_m = 0;
	to.roughness_m = roughness;
	Rng rng(5);
	auto t = std::make_unique<Terrain>(
	    to, -50, -50, 50, 50, 0, 1, [](double, double) { return 1.0; }, rng);
	return World(std::move(t), -50, -50, 50, 50);
}
}  // namespace

TEST(SimConfig, ShippedScenariosLoadStrictly)
{
	for (const char* f :
	     {"ini/sim-tiny.ini", "ini/sim-handheld.ini", "ini/sim-robot.ini"})
	{
		SCOPED_TRACE(f);
		const auto o = SimOptions::loadFile(f);
		EXPECT_EQ(o.lidar.model, "VLP16");
		EXPECT_GE(o.imu.rate_hz, 200);
	}
	EXPECT_EQ(SimOptions::loadFile("ini/sim-robot.ini").motion.motionType(),
	          MotionType::Robot);
}

TEST(SimConfig, BadKeysAndValuesNameFileSectionKey)
{
	expectConfigError("[trees]\nstem_per_ha = 400\n",
	                  {"my.ini", "trees", "stem_per_ha"});
	expectConfigError("[treez]\nstems_per_ha = 400\n", {"my.ini", "treez"});
	expectConfigError("[trees]\nstems_per_ha = lots\n",
	                  {"my.ini", "trees", "stems_per_ha", "lots"});
	expectConfigError("[lidar]\nmodel = VLP17\n", {"my.ini", "lidar", "model"});
	expectConfigError("[motion]\ntype = drone\n", {"my.ini", "motion", "type"});
	expectConfigError("[output]\ngt_rate_hz = 50\n",
	                  {"my.ini", "output", "gt_rate_hz"});
	expectConfigError("[sim]\nnoise = maybe\n", {"my.ini", "sim", "noise"});
	expectConfigError("[lidar]\nrange_noise_classes = stem, leaves\n",
	                  {"my.ini", "lidar", "range_noise_classes", "shrub"});
	EXPECT_NO_THROW(SimOptions::loadText(
	    "[lidar]\nrange_noise_classes = ground, stem shrub\n", "my.ini"));
	EXPECT_NO_THROW(
	    SimOptions::loadText("[trees]\nstems_per_ha = 400\n", "my.ini"));
}

TEST(SimConfig, DumpRoundTripsAndNoiseSwitch)
{
	auto o = SimOptions::loadFile("ini/sim-robot.ini");
	const auto again = SimOptions::loadText(o.toIni(), "dump");
	EXPECT_EQ(again.toIni(), o.toIni());
	o.run.noise = false;
	const auto e = o.effective();
	EXPECT_EQ(e.lidar.range_noise_m, 0);
	EXPECT_EQ(e.lidar.dropout_probability, 0);
	EXPECT_EQ(e.imu.gyro_bias_sigma_rad_s, 0);
	EXPECT_EQ(e.gnss.canopy_sigma_m, 0);
	EXPECT_GT(o.lidar.range_noise_m,
	          0);  // the switch does not edit the options
}

TEST(SimRandom, FixedSequences)
{
	Rng a(42), b(42), c(43);
	for (int i = 0; i < 10; i++)
	{
		const uint64_t x = a.next();
		EXPECT_EQ(x, b.next());
		EXPECT_NE(x, c.next());
	}
	double sum = 0, sum2 = 0;
	for (int i = 0; i < 20000; i++)
	{
		const double v = a.normal();
		sum += v;
		sum2 += v * v;
	}
	EXPECT_NEAR(sum / 20000, 0.0, 0.03);
	EXPECT_NEAR(sum2 / 20000, 1.0, 0.05);
}

TEST(SimBodyTrajectory, RatesAndAccelerationsMatchNumericDerivatives)
{
	// Random smooth-ish control points (big angles on purpose).
	Rng rng(3);
	std::vector<BodyTrajectory::Sample> ctrl;
	for (int k = 0; k < 60; k++)
		ctrl.push_back({rng.uniform(-1, 1), rng.uniform(-1, 1),
		                rng.uniform(-1, 1), 0.1 * k + rng.uniform(-0.1, 0.1),
		                rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3)});
	const BodyTrajectory tr(100.0, 0.05, ctrl);
	const double h = 1e-5;
	// Inside knot intervals: at a knot the third derivative jumps, so a
	// central difference of v straddling it is not a reference.
	for (int k = 0; k < 56; k++)
	{
		const double t = tr.startTime() + (k + 0.37) * 0.05;
		const BodyState s = tr.state(t);
		const BodyState sp = tr.state(t + h), sm = tr.state(t - h);
		EXPECT_LT((s.v - (sp.p - sm.p) / (2 * h)).norm(), 1e-6);
		EXPECT_LT((s.a - (sp.v - sm.v) / (2 * h)).norm(), 1e-5);
		// w_body = log(R(t-h)^T R(t+h)) / 2h
		const Eigen::Vector3d w =
		    rotationLog(sm.R.transpose() * sp.R) / (2 * h);
		EXPECT_LT((s.w_body - w).norm(), 1e-5) << "t=" << t;
		EXPECT_LT((s.dw_body - (sp.w_body - sm.w_body) / (2 * h)).norm(), 1e-4);
		EXPECT_LT((tr.pose(t).linear() - s.R).norm(), 1e-12);
	}
}

TEST(SimBodyTrajectory, ContinuousAccelerationAcrossKnotsAndExactRest)
{
	std::vector<BodyTrajectory::Sample> ctrl(4, {1, 2, 3, 0.5, 0, 0});
	Rng rng(9);
	for (int k = 0; k < 20; k++)
		ctrl.push_back({rng.uniform(-1, 1), rng.uniform(-1, 1), 0,
		                rng.uniform(-1, 1), 0, 0});
	for (int k = 0; k < 4; k++) ctrl.push_back({1, 2, 3, 0.5 + 2 * M_PI, 0, 0});
	const BodyTrajectory tr(0.0, 0.1, ctrl);
	for (int k = 1; k < 24; k++)
	{
		const double tk = 0.1 * k;
		EXPECT_LT((tr.state(tk - 1e-9).a - tr.state(tk + 1e-9).a).norm(), 1e-5);
	}
	// Four equal control points: the curve rests there exactly.
	const Eigen::Isometry3d a = tr.pose(tr.startTime()),
	                        b = tr.pose(tr.endTime());
	EXPECT_EQ(a.translation(), Eigen::Vector3d(1, 2, 3));
	EXPECT_LT((a.linear() - b.linear()).norm(), 1e-12);
	EXPECT_EQ(tr.state(tr.endTime()).v.norm(), 0.0);
}

TEST(SimPrimitives, StemCylinderEllipsoidBox)
{
	double t, c;
	// Upright circular stem of radius 0.2 at the origin, hit from x=-5.
	StemSegment s;
	s.base = Eigen::Vector3d(0, 0, 0);
	s.R = Eigen::Matrix3d::Identity();
	s.z0 = 0;
	s.z1 = 10;
	s.r0 = s.r1 = 0.2;
	ASSERT_TRUE(intersectStem(s, {-5, 0, 1}, {1, 0, 0}, 0, 100, t, c));
	EXPECT_NEAR(t, 4.8, 1e-9);
	EXPECT_NEAR(c, 1.0, 1e-9);
	EXPECT_FALSE(intersectStem(s, {-5, 0.3, 1}, {1, 0, 0}, 0, 100, t, c));
	EXPECT_FALSE(
	    intersectStem(s, {-5, 0, 11}, {1, 0, 0}, 0, 100, t, c));  // above
	EXPECT_FALSE(
	    intersectStem(s, {-5, 0, 1}, {1, 0, 0}, 0, 4.0, t, c));  // t_max
	// Elliptic: semi-axes 0.2*1.1 along x, 0.2*0.9 along y.
	s.sa = 1.1;
	s.sb = 0.9;
	ASSERT_TRUE(intersectStem(s, {-5, 0, 1}, {1, 0, 0}, 0, 100, t, c));
	EXPECT_NEAR(t, 5 - 0.22, 1e-9);
	ASSERT_TRUE(intersectStem(s, {0, -5, 1}, {0, 1, 0}, 0, 100, t, c));
	EXPECT_NEAR(t, 5 - 0.18, 1e-9);
	// Taper: radius 0.3 at z=0 to 0.1 at z=10 -> 0.2 at z=5.
	s.sa = s.sb = 1;
	s.r0 = 0.3;
	s.r1 = 0.1;
	ASSERT_TRUE(intersectStem(s, {-5, 0, 5}, {1, 0, 0}, 0, 100, t, c));
	EXPECT_NEAR(t, 4.8, 1e-9);

	Cylinder cy;
	cy.p0 = Eigen::Vector3d(0, 0, 0);
	cy.axis = Eigen::Vector3d(0, 0, 1);
	cy.length = 2;
	cy.radius = 0.05;
	ASSERT_TRUE(intersectCylinder(cy, {0, -3, 1}, {0, 1, 0}, 0, 100, t, c));
	EXPECT_NEAR(t, 2.95, 1e-9);
	EXPECT_FALSE(intersectCylinder(cy, {0, -3, 2.5}, {0, 1, 0}, 0, 100, t, c));

	Medium m;
	m.center = Eigen::Vector3d(10, 0, 0);
	m.radii = Eigen::Vector3d(2, 1, 1);
	double tin, tout;
	ASSERT_TRUE(intersectEllipsoid(m, {0, 0, 0}, {1, 0, 0}, 0, tin, tout));
	EXPECT_NEAR(tin, 8, 1e-9);
	EXPECT_NEAR(tout, 12, 1e-9);

	Box b;
	b.center = Eigen::Vector3d(10, 0, 1);
	b.half = Eigen::Vector3d(1, 2, 1);
	b.yaw = M_PI / 2;  // now 2 along x, 1 along y
	ASSERT_TRUE(intersectBox(b, {0, 0, 1}, {1, 0, 0}, 0, 100, t, c));
	EXPECT_NEAR(t, 8, 1e-9);
	EXPECT_NEAR(c, 1, 1e-9);
}

TEST(SimTerrain, RaycastMatchesBruteForceAndRespectsSlopeLimit)
{
	TerrainOptions to;
	to.elevation_range_m = 6;
	to.max_slope_deg = 12;
	to.roughness_m = 0.04;
	Rng rng(11);
	const Terrain ter(
	    to, -60, -60, 60, 60, 10, 15, [](double, double) { return 1.0; }, rng);
	EXPECT_LE(ter.stats().max_slope_deg, 12.0 + 1e-6);
	EXPECT_GT(ter.stats().elevation_range_m, 1.0);
	EXPECT_NEAR(ter.smoothHeight(0, 0), 0.0, 1e-9);   // start at height 0
	EXPECT_NEAR(ter.smoothHeight(5, -3), 0.0, 1e-9);  // levelled yard
	Rng r2(12);
	int hits = 0;
	for (int i = 0; i < 300; i++)
	{
		const Eigen::Vector3d o(r2.uniform(-30, 30), r2.uniform(-30, 30), 0);
		const Eigen::Vector3d org(
		    o.x(), o.y(), ter.height(o.x(), o.y()) + r2.uniform(0.5, 3));
		const double el = r2.uniform(-30, 2) * M_PI / 180,
		             az = r2.uniform(0, 2 * M_PI);
		const Eigen::Vector3d d(std::cos(el) * std::cos(az),
		                        std::cos(el) * std::sin(az), std::sin(el));
		// Brute force: 1 mm steps, 0.05 mm within 5 mm of the surface.
		double t_bf = -1;
		for (double t = 0; t < 40;)
		{
			const Eigen::Vector3d p = org + t * d;
			const double gap = p.z() - ter.height(p.x(), p.y());
			if (gap <= 0)
			{
				t_bf = t;
				break;
			}
			t += gap < 0.005 ? 5e-5 : 0.001;
		}
		double t_hit;
		const bool hit = ter.raycast(org, d, 40, t_hit);
		ASSERT_EQ(hit, t_bf >= 0) << "ray " << i;
		if (hit)
		{
			EXPECT_NEAR(t_hit, t_bf, 0.0011) << "ray " << i;
			hits++;
		}
	}
	EXPECT_GT(hits, 150);
}

TEST(SimWorld, GridRaycastMatchesBruteForce)
{
	World w = flatWorld(0.02);
	Rng rng(21);
	std::vector<StemSegment> stems;
	std::vector<Cylinder> cyls;
	std::vector<Box> boxes;
	for (int i = 0; i < 150; i++)
	{
		StemSegment s;
		s.base =
		    Eigen::Vector3d(rng.uniform(-45, 45), rng.uniform(-45, 45), -0.3);
		const double lean = rng.uniform(0, 0.1), dir = rng.uniform(0, 6.28);
		const Eigen::Vector3d a(std::sin(lean) * std::cos(dir),
		                        std::sin(lean) * std::sin(dir), std::cos(lean));
		s.R.col(2) = a;
		s.R.col(0) = a.cross(Eigen::Vector3d::UnitY()).normalized();
		s.R.col(1) = a.cross(s.R.col(0));
		s.z0 = rng.uniform(0, 3);
		s.z1 = s.z0 + rng.uniform(0.5, 15);
		s.r0 = rng.uniform(0.05, 0.4);
		s.r1 = s.r0 * rng.uniform(0.3, 1.0);
		s.sa = 1.03;
		s.sb = 0.97;
		s.tree = static_cast<uint16_t>(i + 1);
		stems.push_back(s);
		w.add(s);
		Cylinder c;
		c.p0 = s.base + 5 * a;
		c.axis = Eigen::Vector3d(rng.uniform(-1, 1), rng.uniform(-1, 1),
		                         rng.uniform(-0.3, 0.3))
		             .normalized();
		c.length = rng.uniform(0.5, 4);
		c.radius = rng.uniform(0.01, 0.05);
		cyls.push_back(c);
		w.add(c);
	}
	Box b;
	b.center = Eigen::Vector3d(0, 20, 2);
	b.half = Eigen::Vector3d(5, 3, 2.2);
	b.yaw = 0.4;
	boxes.push_back(b);
	w.add(b);
	w.finalize(2.0);
	RayScratch scratch;
	int n_obj = 0;
	for (int i = 0; i < 3000; i++)
	{
		const Eigen::Vector3d o(rng.uniform(-30, 30), rng.uniform(-30, 30),
		                        rng.uniform(0.5, 2));
		const double el = rng.uniform(-15, 15) * M_PI / 180,
		             az = rng.uniform(0, 2 * M_PI);
		const Eigen::Vector3d d(std::cos(el) * std::cos(az),
		                        std::cos(el) * std::sin(az), std::sin(el));
		double best = 100, t, c;
		uint8_t label = kLabelNone;
		for (const auto& s : stems)
			if (intersectStem(s, o, d, 0, best, t, c))
				best = t, label = kLabelStem;
		for (const auto& cy : cyls)
			if (intersectCylinder(cy, o, d, 0, best, t, c))
				best = t, label = kLabelCrown;
		for (const auto& bx : boxes)
			if (intersectBox(bx, o, d, 0, best, t, c))
				best = t, label = kLabelStructure;
		double tg;
		if (w.terrain().raycast(o, d, best, tg) && tg < best)
			best = tg, label = kLabelGround;
		const Hit h = w.raycast(o, d, 0, 100, i, scratch);
		ASSERT_EQ(h.label, label) << "ray " << i;
		if (label != kLabelNone)
		{
			EXPECT_NEAR(h.t, best, 1e-9) << "ray " << i;
			n_obj += label != kLabelGround;
		}
	}
	EXPECT_GT(n_obj, 300);
}

TEST(SimWorld, FoliageIsSeeThroughAndDeterministic)
{
	World w = flatWorld();
	Medium m;
	m.center = Eigen::Vector3d(10, 0, 1.5);
	m.radii = Eigen::Vector3d(1, 1, 1);  // 2 m thick along the ray
	m.extinction_per_m = 0.8;
	m.label = kLabelShrub;
	w.add(m);
	w.finalize(2.0);
	RayScratch s;
	int pass = 0;
	const int n = 4000;
	for (int i = 0; i < n; i++)
	{
		const Hit h = w.raycast({0, 0, 1.5}, {1, 0, 0}, 0, 100, i, s);
		if (!h.valid())
			pass++;
		else
		{
			EXPECT_EQ(h.label, kLabelShrub);
			EXPECT_TRUE(h.porous);
			EXPECT_GE(h.t, 9.0 - 1e-9);
			EXPECT_LE(h.t, 11.0 + 1e-9);
		}
		EXPECT_EQ(w.raycast({0, 0, 1.5}, {1, 0, 0}, 0, 100, i, s).t, h.t);
	}
	// Transmission through 2 m at 0.8/m: exp(-1.6) = 0.20.
	EXPECT_NEAR(double(pass) / n, std::exp(-1.6), 0.03);
}

TEST(SimScenario, SeedDeterminesTheWorld)
{
	auto o = SimOptions::loadFile("ini/sim-tiny.ini");
	const Scenario a(o), b(o);
	o.run.seed = 2;
	const Scenario c(o);
	ASSERT_EQ(a.scene().trees.size(), b.scene().trees.size());
	for (size_t i = 0; i < a.scene().trees.size(); i++)
	{
		EXPECT_EQ(a.scene().trees[i].ground, b.scene().trees[i].ground);
		EXPECT_EQ(a.scene().trees[i].dbh_m, b.scene().trees[i].dbh_m);
	}
	EXPECT_NE(a.scene().trees[0].ground, c.scene().trees[0].ground);
	EXPECT_EQ(a.world().primitiveCount(), b.world().primitiveCount());
	const double t = a.body().startTime() + 17.3;
	EXPECT_EQ(a.lidarPoseInMap(t).matrix(), b.lidarPoseInMap(t).matrix());
	EXPECT_NE(a.lidarPoseInMap(t).matrix(), c.lidarPoseInMap(t).matrix());
}

TEST(SimLidar, AllModelsDecodeAndThreadsDoNotChangeTheScan)
{
	auto o = SimOptions::loadFile("ini/sim-tiny.ini");
	const Scenario sc(o);
	struct Case
	{
		const char* model;
		size_t rows, cols;
	};
	for (const Case c : {Case{"VLP16", 16, 1800}, Case{"HDL32", 32, 2250},
						 Case{"OS1-64", 64, 1024}})
	{
		SCOPED_TRACE(c.model);
		LidarOptions lo = sc.options().lidar;
		lo.model = c.model;
		LidarSimulator one(sc.world(), sc.body(), lo, 99, 1);
		LidarSimulator three(sc.world(), sc.body(), lo, 99, 3);
		const auto a = one.scan(150), b = three.scan(150);
		EXPECT_EQ(a->rowCount, c.rows);
		EXPECT_EQ(a->columnCount, c.cols);
		EXPECT_EQ(a->rangeImage, b->rangeImage);
		EXPECT_EQ(a->intensityImage, b->intensityImage);
		EXPECT_EQ(a->rangeOtherLayers.at("gt_label"), b->rangeOtherLayers.at("gt_label"));
		const auto pts = core::unpackRotatingScan(*a);
		EXPECT_GT(pts.points.size(), c.rows * c.cols / 3);
		// Each return's range equals the distance of its point (decoding
		// convention) and its time lies within the sweep.
		for (size_t i = 0; i < pts.points.size(); i += 101)
		{
			const auto& p = pts.points[i];
			EXPECT_NEAR(std::sqrt(p.x * p.x + p.y * p.y + p.z * p.z), p.range_m, 1e-3);
			EXPECT_GE(p.t_s, 0.f);
			EXPECT_LE(p.t_s, static_cast<float>(a->sweepDuration) + 1e-6f);
		}
		EXPECT_NEAR(mrpt::Clock::toDouble(a->timestamp), one.scanTime(150), 1e-6);
	}
	// Without the GT layers.
	LidarOptions lo = sc.options().lidar;
	lo.gt_layers = false;
	EXPECT_TRUE(LidarSimulator(sc.world(), sc.body(), lo, 1, 2).scan(3)->rangeOtherLayers.empty());
}

// range_noise_classes = stem: stem returns get the range noise, the others
// are cast exactly as without noise (same rays, same dropouts).
TEST(SimLidar, RangeNoiseOnTheNamedClassesOnly)
{
	const auto o = SimOptions::loadFile("ini/sim-tiny.ini");
	const Scenario sc(o);
	LidarOptions exact = sc.options().lidar, stems = exact;
	exact.range_noise_m = 0;
	stems.range_noise_classes = "stem";
	EXPECT_EQ(stems.rangeNoiseMask(), 1u << kLabelStem);
	LidarOptions bad;
	bad.range_noise_classes = "stem leaves";
	EXPECT_FALSE(bad.rangeNoiseMask().has_value());
	EXPECT_THROW(LidarSimulator(sc.world(), sc.body(), bad, 7, 1),
	             std::invalid_argument);
	int same = 0, stem_n = 0;
	double stem_ss = 0;
	for (size_t k : {40, 120, 200})
	{
		const auto a =
		    LidarSimulator(sc.world(), sc.body(), exact, 7, 2).scan(k);
		const auto b =
		    LidarSimulator(sc.world(), sc.body(), stems, 7, 2).scan(k);
		const auto& la = a->rangeOtherLayers.at("gt_label");
		for (int r = 0; r < int(a->rowCount); r++)
			for (int c = 0; c < int(a->columnCount); c++)
			{
				if (a->rangeImage(r, c) == 0 || b->rangeImage(r, c) == 0)
					continue;
				const double d = (double(b->rangeImage(r, c)) -
				                  double(a->rangeImage(r, c))) *
				                 a->rangeResolution;
				if (la(r, c) == kLabelStem)
					stem_ss += d * d, stem_n++;
				else
				{
					ASSERT_EQ(d, 0.0) << "label " << la(r, c);
					same++;
				}
			}
	}
	EXPECT_GT(same, 10000);
	ASSERT_GT(stem_n, 200);
	EXPECT_NEAR(std::sqrt(stem_ss / stem_n), stems.range_noise_m, 0.005);
}

TEST(SimLidar, ReturnsMatchTheWorldGeometry)
{
	// A scan cast from the GT pose, unpacked, re-cast point by point:
	// every return lies on a surface of the world (noise off).
	auto o = SimOptions::loadFile("ini/sim-tiny.ini");
	o.run.noise = false;
	const Scenario sc(o);
	LidarSimulator lidar(sc.world(), sc.body(), sc.options().lidar, 5, 2);
	const auto s = lidar.scan(200);
	const auto pts = core::unpackRotatingScan(*s);
	const Eigen::Isometry3d T_bl = sc.options().lidar.mount.toIsometry();
	RayScratch scratch;
	int n = 0;
	const auto* label = pts.layer("gt_label");
	ASSERT_NE(label, nullptr);
	for (size_t i = 0; i < pts.points.size(); i += 37)
	{
		const auto& p = pts.points[i];
		// Foliage and shrub returns depend on the ray's random free path.
		if ((*label)[i] == kLabelCrown || (*label)[i] == kLabelShrub) continue;
		const Eigen::Isometry3d T = sc.body().pose(lidar.scanTime(200) + p.t_s) * T_bl;
		const Eigen::Vector3d dir = T.linear() * Eigen::Vector3d(p.x, p.y, p.z).normalized();
		const Hit h = sc.world().raycast(T.translation(), dir, 0, 200, 12345, scratch);
		// Solid returns must agree to the range quantisation (2 mm) and the
		// float32 point precision; this re-cast may stop in foliage instead.
		if (h.porous) continue;
		ASSERT_TRUE(h.valid()) << "point " << i;
		EXPECT_EQ(h.label, (*label)[i]) << "point " << i;
		EXPECT_NEAR(h.t, p.range_m, 0.003) << "point " << i;
		n++;
	}
	EXPECT_GT(n, 300);
}

TEST(SimMotion, RobotStopsTurnsInPlaceAndReturnsToStart)
{
	auto o = SimOptions::loadFile("ini/sim-robot.ini");
	o.motion.loop_radius_x_m = 12;
	o.motion.loop_radius_y_m = 8;
	o.motion.loops = 2;
	Rng rng(4);
	const PathPlan path = PathPlan::make(o.motion, rng);
	TerrainOptions to = o.terrain;
	Rng rt(5);
	const Terrain ter(
	    to, -40, -30, 40, 50, 5, 10, [](double, double) { return 1.0; }, rt);
	const BodyTrajectory body =
	    planBodyTrajectory(path, o.motion, ter, 1000.0, rng);
	const Eigen::Isometry3d a = body.pose(body.startTime()),
	                        b = body.pose(body.endTime());
	EXPECT_LT((a.translation() - b.translation()).norm(), 1e-9);
	EXPECT_LT(rotationLog(a.linear().transpose() * b.linear()).norm(), 1e-9);
	double v_max = 0, turn_in_place = 0, t_still = 0, slope_pitch = 0;
	const double dt = 0.01;
	for (double t = body.startTime(); t < body.endTime(); t += dt)
	{
		const BodyState s = body.state(t);
		const double v = s.v.head<2>().norm();
		v_max = std::max(v_max, v);
		if (v < 0.02 && std::abs(s.w_body.z()) > 0.3) turn_in_place += dt;
		if (v < 1e-6 && s.w_body.norm() < 1e-6) t_still += dt;
		slope_pitch = std::max(slope_pitch, std::abs(std::asin(-s.R(2, 0))));
	}
	EXPECT_LE(v_max, o.motion.speed_max_mps * 1.02);
	EXPECT_GT(v_max, o.motion.speed_min_mps * 0.9);
	EXPECT_GT(turn_in_place, 8.0);  // eight corners
	EXPECT_GT(t_still, o.motion.start_pause_s + o.motion.end_pause_s - 0.1);
	EXPECT_GT(slope_pitch, 1.0 * M_PI / 180);  // follows the terrain
}

TEST(SimMotion, HandheldWalksWithSwayAndReturnsToStart)
{
	const auto o = SimOptions::loadFile("ini/sim-handheld.ini");
	const Scenario sc(o);  // world + motion only, no sensor data
	const auto& body = sc.body();
	const Eigen::Isometry3d a = sc.lidarPoseInMap(body.startTime());
	const Eigen::Isometry3d b = sc.lidarPoseInMap(body.endTime());
	EXPECT_LT(a.translation().norm(), 1e-9);
	EXPECT_LT(rotationLog(a.linear()).norm(), 1e-9);  // identity: level start
	EXPECT_LT((b.translation()).norm(), 1e-9);
	EXPECT_LT(rotationLog(b.linear()).norm(), 1e-9);
	EXPECT_GT(sc.path().length(), 300);
	double v_sum = 0, n = 0, roll_max = 0;
	for (double t = body.startTime() + 10; t < body.endTime() - 10; t += 0.05)
	{
		const BodyState s = body.state(t);
		v_sum += s.v.head<2>().norm();
		n++;
		roll_max =
		    std::max(roll_max, std::abs(std::atan2(s.R(2, 1), s.R(2, 2))));
	}
	EXPECT_GT(v_sum / n, 0.95);
	EXPECT_LT(v_sum / n, 1.35);
	EXPECT_GT(roll_max * 180 / M_PI, 2.5);
	EXPECT_LT(roll_max * 180 / M_PI, 4.5);
	EXPECT_GT(sc.scene().stats.trees, 1000);
	EXPECT_NEAR(sc.scene().stats.stems_per_ha, 500, 25);
	EXPECT_NEAR(sc.scene().stats.shrub_cover, 0.2, 0.02);
	EXPECT_GE(sc.scene().stats.buildings, 2);
}
