// Ground labelling on a real scan: KITTI odometry sequence 00, frame 0
// (HDL-64E, 124 668 points, sensor 1.73 m above the road, x forward, y
// left; ../shared/data/mrpt/kitti_00_000000.bin.gz, float32 x y z i).
// Boxes hand-picked from height slices of the cloud (0.5 m cells, min/max
// z): road surface in front of, beside and behind the car must be ground;
// two parked cars (one left at x 3..7 m, y 5..8.5 m; a row on the right at
// x 10..17 m, y -6.6..-5.9 m) and a wall (y -9 m) must not.
#include <forest_slam/ground/ground_lattice.h>
#include <forest_slam/io/gz_stream.h>
#include <gtest/gtest.h>

#include <cstring>

using namespace forest_slam;

namespace
{
std::vector<Eigen::Vector3f> readKitti(const std::string& path)
{
	io::GzInputStream in(path);
	std::vector<Eigen::Vector3f> pts;
	float rec[4];
	while (in.Read(rec, sizeof(rec)) == sizeof(rec))
		pts.emplace_back(rec[0], rec[1], rec[2]);
	return pts;
}

struct Box
{
	const char* what;
	float x0, x1, y0, y1, z0, z1;
	bool contains(const Eigen::Vector3f& p) const
	{
		return p.x() >= x0 && p.x() < x1 && p.y() >= y0 && p.y() < y1 &&
		       p.z() >= z0 && p.z() < z1;
	}
};

/** Fraction of the points in `b` labelled ground; `n` their count. */
double groundFraction(const std::vector<Eigen::Vector3f>& pts,
                      const std::vector<uint8_t>& lab, const Box& b, size_t& n)
{
	size_t g = 0;
	n = 0;
	for (size_t i = 0; i < pts.size(); i++)
		if (b.contains(pts[i]))
		{
			n++;
			g += lab[i];
		}
	return n ? double(g) / n : 0;
}
}  // namespace

TEST(GroundKitti, RoadIsGroundCarsAndWallAreNot)
{
	const auto pts = readKitti("../shared/data/mrpt/kitti_00_000000.bin.gz");
	ASSERT_EQ(pts.size(), 124668u);
	ground::GroundLattice g;
	const auto lab = g.labelScan(pts, Eigen::Vector3d::Zero());
	ASSERT_EQ(lab.size(), pts.size());
	const Box road[] = {
	    {"road ahead right", 0, 10, 2, 4.5, -3, 0},
	    {"road ahead", 8, 20, -2, 2, -3, 0},
	    {"road behind", -20, -10, -4, 0, -3, 0},
	};
	for (const auto& b : road)
	{
		size_t n;
		const double f = groundFraction(pts, lab, b, n);
		EXPECT_GT(n, 300u) << b.what;
		EXPECT_GE(f, 0.97) << b.what << ": " << n << " points";
	}
	// Car bodies and the wall from 0.4 m above the road up (the road is at
	// -1.9 m on the left, -1.55 m at the kerb on the right): their lowest
	// returns touch the road and may be within the ground threshold.
	const Box objects[] = {
	    {"parked car left", 3, 7, 5, 8.5, -1.5, 1},
	    {"parked cars right", 10, 17, -6.6, -5.9, -1.15, 1},
	    {"wall right", 10, 17, -9.5, -8.8, -1.15, 2},
	};
	for (const auto& b : objects)
	{
		size_t n;
		const double f = groundFraction(pts, lab, b, n);
		EXPECT_GT(n, 30u) << b.what;
		EXPECT_LE(f, 0.02) << b.what << ": " << n << " points";
	}
	// The terrain model knows the road height in front of the car.
	double z;
	ASSERT_TRUE(g.heightAt(10, 0, z));
	EXPECT_NEAR(z, -1.8, 0.15);
}
