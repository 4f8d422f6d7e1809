// LocalMap's stem model: scan points on a stem are matched to the circle
// fitted to the map's points around them, not to a plane through the
// nearest ones.
#include <forest_slam/core/config.h>
#include <forest_slam/odometry/local_map.h>
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

using forest_slam::odometry::LocalMap;
using forest_slam::odometry::LocalMapOptions;
using forest_slam::odometry::PlaneRow;
using forest_slam::odometry::RegistrationOptions;

namespace
{
constexpr double kDeg = M_PI / 180;

/** Points on the vertical stem (centre c, radius r) between the bearings
 * a0..a1 [deg] and heights 0.5..2 m. */
std::vector<Eigen::Vector3f> arc(const Eigen::Vector2d& c, double r, double a0,
                                 double a1)
{
	std::vector<Eigen::Vector3f> pts;
	for (double z = 0.5; z <= 2.0; z += 0.05)
		for (double a = a0; a <= a1 + 1e-9; a += 4)
			pts.emplace_back(float(c.x() + r * std::cos(a * kDeg)),
			                 float(c.y() + r * std::sin(a * kDeg)), float(z));
	return pts;
}

Eigen::Vector3f onStem(const Eigen::Vector2d& c, double r, double a, double z)
{
	return Eigen::Vector3f(float(c.x() + r * std::cos(a * kDeg)),
	                       float(c.y() + r * std::sin(a * kDeg)), float(z));
}

LocalMapOptions stemOptions(bool stem_model)
{
	LocalMapOptions o;
	o.planar_spacing_m = 0.02;
	o.edge_spacing_m = 0.02;
	// The test stems are sampled densely (1-5 cm): planes from 5 neighbours
	// that close are fine.
	o.min_plane_spread_m = 0.005;
	o.stem_model = stem_model;
	return o;
}

double residual(const PlaneRow& row, const Eigen::Vector3f& x)
{
	return row.n.dot(x.cast<double>()) + row.d;
}
}  // namespace

// The map saw the side of a 30 cm stem facing the sensor (bearings
// 120-240 deg); the next scan sees past the end of that arc (260 deg). The
// plane through the nearest map points is the tangent at ~240 deg, a
// centimetre off the surface there; the stem's circle is on it.
TEST(LocalMap, StemModelMatchesTheSurfaceBeyondTheSeenArc)
{
	const Eigen::Vector2d c(5, 0);
	const double r = 0.15;
	const auto side = arc(c, r, 120, 240);
	const Eigen::Vector3f x = onStem(c, r, 260, 1.2);
	RegistrationOptions ro;
	double err[2];
	for (int stem = 0; stem < 2; stem++)
	{
		LocalMap map(stemOptions(stem == 1));
		map.insert({}, side);
		PlaneRow row;
		ASSERT_TRUE(map.matchPlane(x, 0.3, ro, row)) << "stem model " << stem;
		err[stem] = std::abs(residual(row, x));
	}
	EXPECT_GT(err[0], 0.005) << "plane through the nearest points";
	EXPECT_LT(err[1], 0.001) << "stem circle";
}

// An edge (silhouette) on a stem gives one row, the distance to the stem's
// surface along its radius; the second row carries nothing.
TEST(LocalMap, StemModelEdgeIsOneRadialRow)
{
	const Eigen::Vector2d c(3, 4);
	const double r = 0.2;
	const auto side = arc(c, r, -150, -30);
	LocalMap map(stemOptions(true));
	map.insert(side, side);
	// 1 cm outside the surface at bearing -30 deg.
	const Eigen::Vector3f x = onStem(c, r + 0.01, -30, 1.0);
	RegistrationOptions ro;
	PlaneRow a, b;
	ASSERT_TRUE(map.matchLine(x, 0.3, ro, a, b));
	const Eigen::Vector3d radial(std::cos(-30 * kDeg), std::sin(-30 * kDeg), 0);
	EXPECT_GT(a.n.dot(radial), 0.999);
	EXPECT_NEAR(residual(a, x), 0.01, 0.001);
	EXPECT_EQ(b.n.norm(), 0.0);
	EXPECT_EQ(b.d, 0.0);
}

// A flat wall is no stem: its plane is used (normal across the wall).
TEST(LocalMap, StemModelLeavesWallsToPlanes)
{
	std::vector<Eigen::Vector3f> wall;
	for (double z = 0.5; z <= 2.0; z += 0.05)
		for (double y = -1; y <= 1; y += 0.05)
			wall.emplace_back(6.0f, float(y), float(z));
	LocalMap map(stemOptions(true));
	map.insert({}, wall);
	const Eigen::Vector3f x(6.02f, 0.31f, 1.13f);
	RegistrationOptions ro;
	PlaneRow row;
	ASSERT_TRUE(map.matchPlane(x, 0.3, ro, row));
	EXPECT_GT(std::abs(row.n.x()), 0.999);
	EXPECT_NEAR(std::abs(residual(row, x)), 0.02, 1e-4);
}

// Stem fits are cached per cell while the map is unchanged: after the map
// changes, a query sees the new stem, not the cached fit of the old one.
TEST(LocalMap, StemFitsFollowTheMapWhenItChanges)
{
	const double r = 0.15;
	const Eigen::Vector2d c0(5, 0), c1(5.03, 0);
	LocalMap map(stemOptions(true));
	map.insert({}, arc(c0, r, 120, 240));
	const Eigen::Vector3f x = onStem(c0, r, 180, 1.2);
	RegistrationOptions ro;
	PlaneRow row;
	ASSERT_TRUE(map.matchPlane(x, 0.3, ro, row));
	EXPECT_NEAR(residual(row, x), 0.0, 0.001);
	map.clear();
	map.insert({}, arc(c1, r, 120, 240));  // the stem 3 cm further on
	ASSERT_TRUE(map.matchPlane(x, 0.3, ro, row));
	EXPECT_NEAR(residual(row, x), 0.03, 0.001);
}

// Stem keys out of range are named in the error.
TEST(LocalMap, StemOptionsOutOfRangeAreRejected)
{
	auto cfg = forest_slam::core::TrackedConfig::fromText(
	    "[local_map]\nstem_min_radius_m = 0.2\nstem_max_radius_m = 0.1\n",
	    "lm.ini");
	LocalMapOptions o;
	try
	{
		o.loadFromConfigFile(cfg, "local_map");
		FAIL() << "expected a ConfigError";
	}
	catch (const forest_slam::core::ConfigError& e)
	{
		EXPECT_NE(std::string(e.what()).find("stem_max_radius_m"),
		          std::string::npos)
		    << e.what();
	}
}
