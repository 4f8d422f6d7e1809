#include <forest_slam/core/config.h>
#include <forest_slam/ground/ground_lattice.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace forest_slam;

namespace
{
// Curved, sloped terrain: ~8.5 deg along x plus undulation along y.
double terrain(double x, double y)
{
	return 0.15 * x + 0.5 * std::sin(y / 5.0);
}

struct Scene
{
	std::vector<Eigen::Vector3f> pts;
	std::vector<uint8_t> truth;  // 1 ground
	void add(double x, double y, double z, bool ground)
	{
		pts.emplace_back(x, y, z);
		truth.push_back(ground);
	}
};

/** Ground with 2 cm noise, stems, low shrubs that hide the ground under
 * them completely, and a wall. `hide_ground_in` removes ground points in a
 * disc (e.g. occluded this scan). */
Scene makeScene(uint32_t seed, double hide_x = 1e9, double hide_y = 1e9,
                double hide_r = 0)
{
	std::mt19937 rng(seed);
	std::uniform_real_distribution<double> U(-30, 30);
	std::normal_distribution<double> N(0, 0.02);
	Scene s;
	const std::vector<Eigen::Vector2d> shrubs = {{8, 5}, {-10, -6}, {15, -12}};
	const std::vector<Eigen::Vector2d> stems = {
	    {5, -3}, {-7, 9}, {12, 12}, {-15, -15}};
	for (int k = 0; k < 40000; k++)
	{
		const double x = U(rng), y = U(rng);
		if (std::hypot(x, y) < 4) continue;  // blind zone under the sensor
		bool hidden = std::hypot(x - hide_x, y - hide_y) < hide_r;
		for (const auto& c : shrubs)
			hidden |= std::hypot(x - c.x(), y - c.y()) < 1.5;
		for (const auto& c : stems)
			hidden |= std::hypot(x - c.x(), y - c.y()) < 0.25;
		if (!hidden) s.add(x, y, terrain(x, y) + N(rng), true);
	}
	std::uniform_real_distribution<double> A(0, 2 * M_PI), H(0, 1);
	for (const auto& c : shrubs)  // shrub: 0.3..1.0 m above ground, dense
		for (int k = 0; k < 1500; k++)
		{
			const double a = A(rng), r = 1.5 * std::sqrt(H(rng));
			const double x = c.x() + r * std::cos(a),
			             y = c.y() + r * std::sin(a);
			s.add(x, y, terrain(x, y) + 0.3 + 0.7 * H(rng), false);
		}
	for (const auto& c : stems)  // stem base up to 8 m
		for (int k = 0; k < 2000; k++)
		{
			const double a = A(rng);
			const double x = c.x() + 0.2 * std::cos(a),
			             y = c.y() + 0.2 * std::sin(a);
			s.add(x, y, terrain(c.x(), c.y()) + 8 * H(rng) + 0.02, false);
		}
	for (int k = 0; k < 3000; k++)  // a wall (building) from 0.05 m up
	{
		const double y = 20 + 6 * H(rng), x = -20;
		s.add(x, y, terrain(x, y) + 0.05 + 3 * H(rng), false);
	}
	return s;
}

struct Score
{
	double precision, recall;
};
Score score(const Scene& s, const std::vector<uint8_t>& lab)
{
	double tp = 0, fp = 0, fn = 0;
	for (size_t i = 0; i < lab.size(); i++)
	{
		if (lab[i] && s.truth[i]) tp++;
		if (lab[i] && !s.truth[i]) fp++;
		if (!lab[i] && s.truth[i]) fn++;
	}
	return {tp / std::max(1.0, tp + fp), tp / std::max(1.0, tp + fn)};
}
}  // namespace

TEST(GroundLattice, LabelsCurvedSlopedTerrainWithShrubsAndStems)
{
	const auto s = makeScene(1);
	ground::GroundLattice g;
	const auto lab = g.labelScan(s.pts, {0, 0, 1.6});
	const auto sc = score(s, lab);
	EXPECT_GE(sc.precision, 0.98);
	EXPECT_GE(sc.recall, 0.97);
	// Points 2 cm above the ground at a stem base must not be ground... a few
	// are (within the threshold); the bulk of every stem is not.
	size_t stem_ground = 0, stem_total = 0;
	for (size_t i = 0; i < s.pts.size(); i++)
		if (!s.truth[i] &&
		    s.pts[i].z() - terrain(s.pts[i].x(), s.pts[i].y()) > 0.5)
		{
			stem_total++;
			stem_ground += lab[i];
		}
	EXPECT_LT(static_cast<double>(stem_ground) / stem_total, 0.01);
}

TEST(GroundLattice, TerrainModelFollowsTheGround)
{
	const auto s = makeScene(2);
	ground::GroundLattice g;
	g.labelScan(s.pts, {0, 0, 1.6});
	double worst = 0, sum2 = 0;
	int n = 0;
	Eigen::Vector2d worst_at(0, 0);
	for (double x = -25; x <= 25; x += 2.3)
		for (double y = -25; y <= 25; y += 2.3)
		{
			if (std::hypot(x, y) < 6) continue;
			double z;
			if (!g.heightAt(x, y, z)) continue;
			const double e = std::abs(z - terrain(x, y));
			if (e > worst)
			{
				worst = e;
				worst_at = {x, y};
			}
			sum2 += e * e;
			n++;
		}
	EXPECT_GT(n, 300);
	EXPECT_LT(std::sqrt(sum2 / n), 0.04);
	EXPECT_LT(worst, 0.15) << "at " << worst_at.transpose();
	double z;
	EXPECT_FALSE(g.heightAt(500, 500, z));
}

TEST(GroundLattice, TemporalPriorCoversGroundHiddenThisScan)
{
	ground::GroundLattice g;
	const auto first = makeScene(3);
	g.labelScan(first.pts, {0, 0, 1.6});
	// Second scan: a 4 m disc of ground is occluded and a dense low shrub
	// sits there (seen from above, no ground under it). Without the prior the
	// shrub's lowest points would look like ground.
	auto second = makeScene(4, -12, 10, 4.0);
	std::mt19937 rng(9);
	std::uniform_real_distribution<double> H(0, 1);
	const size_t before = second.pts.size();
	for (int k = 0; k < 4000; k++)
	{
		const double a = 2 * M_PI * H(rng), r = 4 * std::sqrt(H(rng));
		const double x = -12 + r * std::cos(a), y = 10 + r * std::sin(a);
		second.add(x, y, terrain(x, y) + 0.45 + 0.5 * H(rng), false);
	}
	const auto lab = g.labelScan(second.pts, {0, 0, 1.6});
	size_t wrong = 0;
	for (size_t i = before; i < lab.size(); i++) wrong += lab[i];
	EXPECT_LT(static_cast<double>(wrong) / (lab.size() - before), 0.02);

	ground::GroundLattice fresh;
	const auto lab2 = fresh.labelScan(second.pts, {0, 0, 1.6});
	size_t wrong_fresh = 0;
	for (size_t i = before; i < lab2.size(); i++) wrong_fresh += lab2[i];
	EXPECT_GT(wrong_fresh, wrong) << "the prior is what saves this case";
}

TEST(GroundLattice, GrazingBandDropsFarLowFoliageOnly)
{
	// Flat ground seen from 1.5 m, and two patches of low foliage 8 cm above
	// it among the ground returns: one at 30 m (grazing beams), one at 8 m.
	std::mt19937 rng(5);
	std::uniform_real_distribution<double> A(0, 2 * M_PI), H(0, 1);
	std::normal_distribution<double> N(0, 0.005);
	Scene s;
	std::vector<int> patch;  // 0 none, 1 near, 2 far (foliage points)
	for (int k = 0; k < 40000; k++)
	{
		const double a = A(rng), r = std::sqrt(9 + (38 * 38 - 9) * H(rng));
		s.add(r * std::cos(a), r * std::sin(a), N(rng), true);
		patch.push_back(0);
	}
	for (int which : {1, 2})
		for (int k = 0; k < 60; k++)
		{
			const double a = A(rng), r = 2 * std::sqrt(H(rng));
			const double cx = which == 1 ? 8 : 30;
			s.add(cx + r * std::cos(a), r * std::sin(a), 0.08 + N(rng), false);
			patch.push_back(which);
		}
	auto foliageAsGround = [&](const std::vector<uint8_t>& lab, int which)
	{
		size_t n = 0, g = 0;
		for (size_t i = 0; i < lab.size(); i++)
			if (patch[i] == which) n++, g += lab[i];
		return static_cast<double>(g) / n;
	};
	auto farRecall = [&](const std::vector<uint8_t>& lab)
	{
		size_t n = 0, g = 0;
		for (size_t i = 0; i < lab.size(); i++)
			if (s.truth[i] && s.pts[i].head<2>().norm() > 25) n++, g += lab[i];
		return static_cast<double>(g) / n;
	};
	ground::GroundOptions full;  // max_band_length_m = 0: the full band
	const auto lab_full =
	    ground::GroundLattice(full).labelScan(s.pts, {0, 0, 1.5});
	ground::GroundOptions band;
	band.max_band_length_m = 0.6;  // 3 cm thick at 30 m, 11 cm at 8 m
	const auto lab_band =
	    ground::GroundLattice(band).labelScan(s.pts, {0, 0, 1.5});
	EXPECT_GT(foliageAsGround(lab_full, 2), 0.9);
	// (Not all: the foliage also lifts the node planes a little.)
	EXPECT_LT(foliageAsGround(lab_band, 2), 0.3);
	// Steep beams keep the full threshold: the near patch stays ground (no
	// way to tell it from a bump there), and the far ground stays ground.
	EXPECT_GT(foliageAsGround(lab_band, 1), 0.9);
	EXPECT_GT(farRecall(lab_band), 0.97);
}

TEST(GroundLattice, IgnoresNaNsAndFarPoints)
{
	ground::GroundLattice g;
	std::vector<Eigen::Vector3f> pts = {{NAN, 0, 0}, {100, 0, 0}};
	const auto lab = g.labelScan(pts, {0, 0, 0});
	EXPECT_EQ(lab, std::vector<uint8_t>({0, 0}));
}

TEST(GroundLattice, OptionsAreValidated)
{
	auto cfg = core::TrackedConfig::fromText("[ground]\nnode_spacing_m = 0\n",
	                                         "g.ini");
	ground::GroundOptions o;
	EXPECT_THROW(o.loadFromConfigFile(cfg, "ground"), core::ConfigError);
	auto neg = core::TrackedConfig::fromText(
	    "[ground]\nmax_band_length_m = -1\n", "g.ini");
	EXPECT_THROW(o.loadFromConfigFile(neg, "ground"), core::ConfigError);
}
