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
using forest_slam::odometry::MatchReach;
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
	o.stem_model_planar = stem_model;  // planar matches exercise the circle
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
		MatchReach reach;
		ASSERT_TRUE(map.matchPlane(x, 0.3, ro, row, reach))
		    << "stem model " << stem;
		err[stem] = std::abs(residual(row, x));
	}
	EXPECT_GT(err[0], 0.005) << "plane through the nearest points";
	EXPECT_LT(err[1], 0.001) << "stem circle";
}

// With stem_model_planar off (the default) a planar point keeps the plane
// through the nearest map points even on a stem; an edge on the same stem
// still gets the circle's radial row.
TEST(LocalMap, StemModelForPlanarMatchesIsOptional)
{
	const Eigen::Vector2d c(5, 0);
	const double r = 0.15;
	const auto side = arc(c, r, 120, 240);
	LocalMapOptions o = stemOptions(true);
	o.stem_model_planar = false;
	EXPECT_FALSE(LocalMapOptions().stem_model_planar);
	LocalMap map(o);
	map.insert(side, side);
	RegistrationOptions ro;
	PlaneRow row, a, b;
	MatchReach reach;
	const Eigen::Vector3f x = onStem(c, r, 260, 1.2);
	ASSERT_TRUE(map.matchPlane(x, 0.3, ro, row, reach));
	EXPECT_GT(std::abs(residual(row, x)), 0.005) << "plane, not the circle";
	const Eigen::Vector3f e = onStem(c, r + 0.01, 240, 1.0);
	ASSERT_TRUE(map.matchLine(e, 0.3, ro, a, b, reach));
	EXPECT_NEAR(residual(a, e), 0.01, 0.001) << "the circle's radial row";
	EXPECT_EQ(b.n.norm(), 0.0);
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
	MatchReach reach;
	ASSERT_TRUE(map.matchLine(x, 0.3, ro, a, b, reach));
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
	MatchReach reach;
	ASSERT_TRUE(map.matchPlane(x, 0.3, ro, row, reach));
	EXPECT_GT(std::abs(row.n.x()), 0.999);
	EXPECT_NEAR(std::abs(residual(row, x)), 0.02, 1e-4);
}

// A match says the smallest gate it passes (registerFeatures keeps it while
// the gate shrinks): at that gate the search gives the same row; below it,
// none or another match that passes the smaller gate. For the wall's plane,
// a stem's surface (plane and edge features) and the coarse fallback.
TEST(LocalMap, MatchesSayTheSmallestGateTheyPass)
{
	std::vector<Eigen::Vector3f> wall, sparse;
	for (double z = 0.5; z <= 2.0; z += 0.05)
		for (double y = -1; y <= 1; y += 0.05)
			wall.emplace_back(6.0f, float(y), float(z));
	// Ground rings 0.6 m apart: no 5 neighbours within 0.5 m, only the
	// coarse voxels' plane.
	for (double x = -10.9; x <= -9.1; x += 0.6)
		for (double y = 0.05; y <= 1.95; y += 0.02)
			sparse.emplace_back(float(x), float(y), 0.0f);
	const Eigen::Vector2d c(3, 4);
	const double r = 0.2;
	const auto stem = arc(c, r, -150, -30);
	LocalMap map(stemOptions(true));
	map.insert(stem, wall);
	map.insert({}, stem);
	map.insert({}, sparse);
	RegistrationOptions ro;
	const std::vector<Eigen::Vector3f> planar_queries = {
	    {6.02f, 0.31f, 1.13f},          // wall, 2 cm off
	    onStem(c, r + 0.04, -90, 1.0),  // stem, 4 cm off
	    {-9.5f, 1.0f, 0.07f}};          // coarse ground plane, 7 cm above
	for (const auto& x : planar_queries)
	{
		PlaneRow row, again;
		MatchReach reach, reach2;
		ASSERT_TRUE(map.matchPlane(x, 0.3, ro, row, reach)) << x.transpose();
		EXPECT_GT(reach.gate_needed, 0.01) << x.transpose();
		if (x.x() < 0)  // the coarse plane: its distance, not a neighbour's
		{
			EXPECT_NEAR(reach.gate_needed, 0.07, 0.005);
		}
		EXPECT_LE(std::abs(residual(row, x)), reach.gate_needed + 1e-9);
		ASSERT_TRUE(
		    map.matchPlane(x, reach.gate_needed + 1e-6, ro, again, reach2));
		EXPECT_EQ(again.n, row.n) << x.transpose();
		EXPECT_EQ(again.d, row.d) << x.transpose();
		EXPECT_EQ(reach2.gate_needed, reach.gate_needed);
		const double below = reach.gate_needed - 0.005;
		if (map.matchPlane(x, below, ro, again, reach2))
		{
			EXPECT_LE(reach2.gate_needed, below) << x.transpose();
		}
	}
	const Eigen::Vector3f e = onStem(c, r + 0.03, -30, 1.0);
	PlaneRow a, b, a2, b2;
	MatchReach reach, reach2;
	ASSERT_TRUE(map.matchLine(e, 0.3, ro, a, b, reach));
	// The stem surface's row (3 cm) or the nearest edge point, a little
	// farther.
	EXPECT_GE(reach.gate_needed, 0.03 - 0.001);
	EXPECT_LT(reach.gate_needed, 0.04);
	ASSERT_TRUE(map.matchLine(e, reach.gate_needed + 1e-6, ro, a2, b2, reach2));
	EXPECT_EQ(a2.n, a.n);
	EXPECT_EQ(a2.d, a.d);
	const double below = reach.gate_needed - 0.005;
	if (map.matchLine(e, below, ro, a2, b2, reach2))
	{
		EXPECT_LE(reach2.gate_needed, below);
	}
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
	MatchReach reach;
	ASSERT_TRUE(map.matchPlane(x, 0.3, ro, row, reach));
	EXPECT_NEAR(residual(row, x), 0.0, 0.001);
	map.clear();
	map.insert({}, arc(c1, r, 120, 240));  // the stem 3 cm further on
	ASSERT_TRUE(map.matchPlane(x, 0.3, ro, row, reach));
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

namespace
{
/** Ground round a lidar at the origin, rough along the 8 m ring (±8 cm
 * every 0.45 m) and flat across it, or flat (amplitude 0). */
Eigen::Vector3f ground(double radius, double bearing_deg, double amplitude)
{
	const double s = 8.0 * bearing_deg * kDeg;  // arc length on the ring
	return Eigen::Vector3f(float(radius * std::cos(bearing_deg * kDeg)),
	                       float(radius * std::sin(bearing_deg * kDeg)),
	                       float(amplitude * std::sin(2 * M_PI * s / 0.45)));
}
}  // namespace

// Seen from one viewpoint, the ground's map points lie along rings. The
// plane through one ring's neighbours holds the ring and the terrain's ups
// and downs along it: a wall round the viewpoint, not the ground. A point
// of the next scan, 10 cm further out after the lidar moved, is 10 cm off
// that wall and would be pulled back towards the old viewpoint. With
// min_plane_spread_ratio the ring is no plane; flat ground seen from
// several places (rings 10 cm apart) still is.
TEST(LocalMap, OneRingOfGroundIsNoPlane)
{
	LocalMapOptions o;
	o.planar_spacing_m = 0.15;
	o.coarse_voxel_m = 0;  // the k neighbours' plane alone
	o.stem_model = false;
	std::vector<Eigen::Vector3f> ring, rings;
	for (double a = -10; a <= 10; a += 0.2)
		ring.push_back(ground(8.0, a, 0.08));
	for (double r = 7.5; r <= 8.5 + 1e-9; r += 0.1)
		for (double a = -10; a <= 10; a += 0.2)
			rings.push_back(ground(r, a, 0));
	const Eigen::Vector3f x = ground(8.1, 1.0, 0.08);

	RegistrationOptions ro;
	EXPECT_EQ(ro.min_plane_spread_ratio, 0.0);
	PlaneRow row;
	MatchReach reach;
	LocalMap one(o);
	one.insert({}, ring);
	ASSERT_TRUE(one.matchPlane(x, 0.3, ro, row, reach));
	EXPECT_LT(std::abs(row.n.z()), 0.5) << "a wall";
	EXPECT_NEAR(std::abs(residual(row, x)), 0.1, 0.02) << "pulled back 10 cm";

	ro.min_plane_spread_ratio = 0.25;
	EXPECT_FALSE(one.matchPlane(x, 0.3, ro, row, reach));
	LocalMap several(o);
	several.insert({}, rings);
	const Eigen::Vector3f y = ground(8.1, 1.0, 0);
	ASSERT_TRUE(several.matchPlane(y, 0.3, ro, row, reach));
	EXPECT_GT(std::abs(row.n.z()), 0.99);
	EXPECT_LT(std::abs(residual(row, y)), 0.001);
}
