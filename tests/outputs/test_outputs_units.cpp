// Units of libs/outputs on synthetic data with known answers: LAS 1.4 bytes,
// georeference, dense map, OctoMap ray casting, classification and DTM,
// tree lists, stand table, report.
#include "test_files.h"

#include <forest_slam/io/las.h>
#include <forest_slam/outputs/classification.h>
#include <forest_slam/outputs/dense_map.h>
#include <forest_slam/outputs/georeference.h>
#include <forest_slam/outputs/octomap_export.h>
#include <forest_slam/outputs/report.h>
#include <forest_slam/outputs/tree_export.h>
#include <forest_slam/trees/tree_options.h>
#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <GeographicLib/UTMUPS.hpp>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <set>
#include <sstream>

using namespace forest_slam;
namespace fs = std::filesystem;

namespace
{
using test_support::readText;
fs::path tempDir(const std::string& name)
{
	return test_support::freshTempDir(name);
}

std::vector<char> slurp(const fs::path& p)
{
	const auto s = readText(p);
	return {s.begin(), s.end()};
}

template <typename T>
T at(const std::vector<char>& d, size_t off)
{
	T v;
	std::memcpy(&v, d.data() + off, sizeof(T));
	return v;
}
}  // namespace

TEST(LasWriter, HeaderFieldsFollowTheLas14Specification)
{
	const auto dir = tempDir("las");
	io::PointCloudFile c;
	std::mt19937 rng(3);
	std::uniform_real_distribution<double> u(-20, 20);
	const size_t n = 5000;
	for (size_t k = 0; k < n; k++)
	{
		c.xyz.emplace_back(500000 + u(rng), 6000000 + u(rng),
		                   100 + u(rng) / 10);
		c.intensity.push_back(static_cast<uint16_t>(k * 13));
		c.classification.push_back(static_cast<uint8_t>(k % 2 ? 2 : 64));
		c.gps_time_s.push_back(4e8 + 0.001 * k);
		c.scan_angle_deg.push_back(static_cast<float>(-15 + 30.0 * k / n));
	}
	outputs::GeoOptions go;
	go.mode = "utm";
	go.utm_zone = 33;
	const auto geo = outputs::Georeference::fromOptions(go);
	io::LasWriteOptions lo;
	lo.wkt = geo->wkt();
	const auto path = dir / "t.las";
	io::writeLas(path.string(), c, lo);

	const auto d = slurp(path);
	const uint32_t wkt_len = static_cast<uint32_t>(lo.wkt.size() + 1);
	ASSERT_EQ(d.size(), 375u + 54u + wkt_len + n * 30u);
	EXPECT_EQ(std::string(d.data(), 4), "LASF");
	EXPECT_EQ(at<uint16_t>(d, 6), 1u | 16u);  // adjusted GPS time, WKT
	EXPECT_EQ(d[24], 1);
	EXPECT_EQ(d[25], 4);
	EXPECT_EQ(at<uint16_t>(d, 94), 375u);                  // header size
	EXPECT_EQ(at<uint32_t>(d, 96), 375u + 54u + wkt_len);  // point offset
	EXPECT_EQ(at<uint32_t>(d, 100), 1u);                   // VLRs
	EXPECT_EQ(static_cast<uint8_t>(d[104]), 6u);           // point format
	EXPECT_EQ(at<uint16_t>(d, 105), 30u);                  // record length
	EXPECT_EQ(at<uint32_t>(d, 107), 0u);  // legacy count: 0 for format 6
	for (int i = 0; i < 5; i++) EXPECT_EQ(at<uint32_t>(d, 111 + 4 * i), 0u);
	EXPECT_EQ(at<uint64_t>(d, 247), n);  // number of point records
	EXPECT_EQ(at<uint64_t>(d, 255), n);  // all are return 1
	for (int i = 1; i < 15; i++) EXPECT_EQ(at<uint64_t>(d, 255 + 8 * i), 0u);
	EXPECT_EQ(at<uint32_t>(d, 243), 0u);  // EVLRs
	// Bounds: max/min pairs for x, y, z equal the data's (to the scale).
	for (int i = 0; i < 3; i++)
	{
		double lo_v = 1e300, hi_v = -1e300;
		for (const auto& p : c.xyz)
			lo_v = std::min(lo_v, p[i]), hi_v = std::max(hi_v, p[i]);
		EXPECT_NEAR(at<double>(d, 179 + 16 * i), hi_v, 0.0006) << "axis " << i;
		EXPECT_NEAR(at<double>(d, 187 + 16 * i), lo_v, 0.0006) << "axis " << i;
		EXPECT_DOUBLE_EQ(at<double>(d, 131 + 8 * i), 0.001);
	}
	// The WKT VLR.
	EXPECT_EQ(std::string(d.data() + 375 + 2), "LASF_Projection");
	EXPECT_EQ(at<uint16_t>(d, 375 + 18), 2112u);
	EXPECT_EQ(at<uint16_t>(d, 375 + 20), wkt_len);
	EXPECT_EQ(std::string(d.data() + 375 + 54), lo.wkt);
	EXPECT_NE(lo.wkt.find("UTM zone 33N"), std::string::npos);
	EXPECT_NE(lo.wkt.find("\"32633\""), std::string::npos);
	// Point record 0: return byte and classification at their offsets.
	const size_t r0 = 375 + 54 + wkt_len;
	EXPECT_EQ(static_cast<uint8_t>(d[r0 + 14]), 0x11u);  // return 1 of 1
	EXPECT_EQ(static_cast<uint8_t>(d[r0 + 16]), 64u);

	// Our reader gets every attribute back.
	const auto back = io::readLas(path.string());
	ASSERT_EQ(back.size(), n);
	for (size_t k = 0; k < n; k += 97)
	{
		EXPECT_LT((back.xyz[k] - c.xyz[k]).norm(), 0.001);
		EXPECT_EQ(back.intensity[k], c.intensity[k]);
		EXPECT_EQ(back.classification[k], c.classification[k]);
		EXPECT_DOUBLE_EQ(back.gps_time_s[k], c.gps_time_s[k]);
		EXPECT_NEAR(back.scan_angle_deg[k], c.scan_angle_deg[k], 0.0031);
	}
}

TEST(LasWriter, RejectsCloudsTooWideForTheScaleAndMismatchedAttributes)
{
	const auto dir = tempDir("las_bad");
	io::PointCloudFile c;
	c.xyz = {{0, 0, 0}, {5e6, 0, 0}};
	EXPECT_THROW(io::writeLas((dir / "wide.las").string(), c),
	             io::CloudFileError);
	c.xyz = {{0, 0, 0}, {1, 0, 0}};
	c.intensity = {1};
	EXPECT_THROW(io::writeLas((dir / "attr.las").string(), c),
	             io::CloudFileError);
	EXPECT_FALSE(fs::exists(dir / "wide.las"));
	EXPECT_FALSE(fs::exists(dir / "attr.las"));
}

TEST(LasWriter, GpsTimeIsAdjustedStandardGpsTime)
{
	// 2017-01-01T00:00:00Z = UNIX 1483228800 = GPS week 1930, 18 leap s.
	EXPECT_DOUBLE_EQ(io::unixToAdjustedGpsTime(1483228800.0),
	                 1483228800.0 - 315964800.0 + 18.0 - 1e9);
}

TEST(Georeference, UtmOffsetModeAddsTheOffsetAndKnowsItsZone)
{
	outputs::GeoOptions o;
	o.mode = "utm";
	o.utm_zone = 32;
	o.utm_offset_e_m = 500000;
	o.utm_offset_n_m = 5000000;
	o.utm_offset_h_m = 200;
	const auto g = outputs::Georeference::fromOptions(o);
	ASSERT_TRUE(g);
	const auto p = g->toProjected({10, 20, 1});
	EXPECT_DOUBLE_EQ(p.x(), 500010);
	EXPECT_DOUBLE_EQ(p.y(), 5000020);
	EXPECT_DOUBLE_EQ(p.z(), 201);
	// Easting 500000 is the central meridian of zone 32: 9 deg east.
	const auto ll = g->toLatLon({0, 0, 0});
	EXPECT_NEAR(ll.lon_deg, 9.0, 1e-9);
	EXPECT_NEAR(ll.lat_deg, 45.1535, 0.001);  // northing 5000 km
	EXPECT_EQ(g->epsg(), 32632);
	o.mode = "none";
	EXPECT_FALSE(outputs::Georeference::fromOptions(o));
}

TEST(Georeference, EnuOriginGoesToTheOriginsUtmZone)
{
	outputs::GeoOptions o;
	o.mode = "enu_origin";
	o.origin_lat_deg = 59.66;  // a Norwegian forest
	o.origin_lon_deg = 10.77;
	o.origin_alt_m = 100;
	const auto g = outputs::Georeference::fromOptions(o);
	ASSERT_TRUE(g);
	EXPECT_EQ(g->utmZone(), 32);
	int zone;
	bool north;
	double e0, n0;
	GeographicLib::UTMUPS::Forward(o.origin_lat_deg, o.origin_lon_deg, zone,
	                               north, e0, n0);
	const auto p0 = g->toProjected({0, 0, 0});
	EXPECT_NEAR(p0.x(), e0, 1e-6);
	EXPECT_NEAR(p0.y(), n0, 1e-6);
	EXPECT_NEAR(p0.z(), 100, 1e-6);
	// 100 m east and 50 m north: the same distance on the grid (UTM scale
	// ~0.9997 here, meridian convergence rotates by ~1.4 deg).
	const auto p1 = g->toProjected({100, 50, 0});
	EXPECT_NEAR((p1 - p0).head<2>().norm(), std::hypot(100, 50), 0.1);
	EXPECT_NEAR(p1.z(), 100, 0.01);
	const auto ll = g->toLatLon({0, 0, 0});
	EXPECT_NEAR(ll.lat_deg, 59.66, 1e-9);
}

TEST(DenseMap, KeepsTheFirstPointOfEveryVoxel)
{
	outputs::DenseMap m(0.05);
	std::mt19937 rng(1);
	std::uniform_real_distribution<float> u(-30, 30);
	std::set<std::tuple<long, long, long>> voxels;
	size_t kept = 0;
	for (int k = 0; k < 200000; k++)
	{
		outputs::DensePoint p;
		p.xyz = {u(rng), u(rng), u(rng) / 20};
		p.intensity = static_cast<uint16_t>(k);
		const bool is_new = voxels
		                        .emplace(std::floor(p.xyz.x() / 0.05),
		                                 std::floor(p.xyz.y() / 0.05),
		                                 std::floor(p.xyz.z() / 0.05))
		                        .second;
		EXPECT_EQ(m.add(p), is_new);
		kept += is_new;
	}
	EXPECT_EQ(m.size(), kept);
	EXPECT_EQ(m.size(), voxels.size());
	// The first point of a voxel stays, with its own attributes.
	outputs::DensePoint a, b;
	a.xyz = b.xyz = {100.01f, 0.01f, 0.01f};
	a.intensity = 7;
	b.intensity = 9;
	EXPECT_TRUE(m.add(a));
	EXPECT_FALSE(m.add(b));
	EXPECT_EQ(m.points().back().intensity, 7);
}

// Firing-order input: 16 rings, one column after another, 1 cm apart
// along each ring, so most voxels are hit by several columns in a row, then
// the same rings again after tens of thousands of other claims, across
// 20 m tiles. Every add agrees with a set of the voxels seen.
TEST(DenseMap, VoxelsHitInRunsAndRevisitedAreKeptOnce)
{
	outputs::DenseMap m(0.05, 20.0);
	std::set<std::tuple<long, long, long>> voxels;
	size_t adds = 0;
	auto sweep = [&](float z0)
	{
		for (int col = 0; col < 3000; col++)
			for (int ring = 0; ring < 16; ring++)
			{
				outputs::DensePoint p;
				const float a = 0.01f * col / (3 + ring);  // radians
				const float r = 3.0f + ring;
				p.xyz = {r * std::cos(a), r * std::sin(a), z0 + 0.1f * ring};
				const bool is_new = voxels
				                        .emplace(std::floor(p.xyz.x() / 0.05),
				                                 std::floor(p.xyz.y() / 0.05),
				                                 std::floor(p.xyz.z() / 0.05))
				                        .second;
				ASSERT_EQ(m.add(p), is_new) << col << " " << ring;
				adds++;
			}
	};
	sweep(0.0f);
	const size_t first = m.size();
	EXPECT_LT(first, adds / 4);  // most adds hit a voxel taken just before
	sweep(5.0f);                 // 48,000 claims of other voxels between
	sweep(0.0f);                 // the first sweep's voxels, all taken
	EXPECT_EQ(m.size(), voxels.size());
	EXPECT_EQ(m.size(), 2 * first);
}

namespace
{
/** Scene for ray casting: ground z=0, stems (vertical cylinders r=0.2) and
 * a wall y=8 behind them. */
struct Scene
{
	std::vector<Eigen::Vector2d> stems = {{3, 3}, {6, 3}};
	double radius = 0.2;
	double hit(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const
	{
		double best = 1e9;
		if (d.z() < -1e-9) best = std::min(best, -o.z() / d.z());
		if (d.y() > 1e-9) best = std::min(best, (8 - o.y()) / d.y());
		for (const auto& s : stems)
		{
			const Eigen::Vector2d o2 = o.head<2>() - s, d2 = d.head<2>();
			const double a = d2.squaredNorm(), b = o2.dot(d2),
			             c = o2.squaredNorm() - radius * radius,
			             disc = b * b - a * c;
			if (a > 1e-12 && disc >= 0)
			{
				const double t = (-b - std::sqrt(disc)) / a;
				if (t > 0) best = std::min(best, t);
			}
		}
		return best;
	}
};

outputs::Keyframes sceneKeyframes(const Scene& s)
{
	outputs::Keyframes kfs;
	const std::vector<std::pair<Eigen::Vector3d, double>> poses = {
	    {{0, 0, 1.5}, 0.0}, {{4.5, 0, 1.5}, M_PI / 2}, {{9, 0, 1.5}, M_PI}};
	for (const auto& [o, yaw] : poses)
	{
		outputs::KeyframeCloud kf;
		kf.sensor_pose.translation() = o;
		kf.sensor_pose.linear() =
		    Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
		for (double az = 0; az < 2 * M_PI; az += 0.006)
			for (double el = -0.5; el <= 0.3; el += 0.02)
			{
				const Eigen::Vector3d d(std::cos(el) * std::cos(az),
				                        std::cos(el) * std::sin(az),
				                        std::sin(el));
				const double t = s.hit(o, d);
				if (t < 20)
					kf.points.push_back(
					    (kf.sensor_pose.inverse() * (o + t * d)).cast<float>());
			}
		kfs.push_back(kf);
	}
	return kfs;
}
}  // namespace

TEST(Octomap, StemsOccupiedSpaceBetweenThemFreeReadByOctomap)
{
	const auto dir = tempDir("octomap");
	const Scene scene;
	const auto kfs = sceneKeyframes(scene);
	const auto bt = (dir / "map.bt").string(), ot = (dir / "map.ot").string();
	const auto s = outputs::writeOctomap(kfs, 0.1, 25, bt, ot);
	EXPECT_EQ(s.keyframes, 3u);
	EXPECT_GT(s.occupied_leaves, 1000u);
	EXPECT_GT(s.free_leaves, 1000u);

	octomap::OcTree tree(0.1);
	ASSERT_TRUE(tree.readBinary(bt));
	EXPECT_DOUBLE_EQ(tree.getResolution(), 0.1);
	const auto occupied = [&](double x, double y, double z)
	{
		const auto* n = tree.search(x, y, z);
		return n && tree.isNodeOccupied(n);
	};
	const auto known_free = [&](double x, double y, double z)
	{
		const auto* n = tree.search(x, y, z);
		return n && !tree.isNodeOccupied(n);
	};
	int stem_occ = 0, stem_total = 0;
	for (const auto& st : scene.stems)
		for (double z = 0.5; z <= 2.5; z += 0.25)
		{
			// The side of the stem facing the sensors' path (y = 0).
			stem_total++;
			stem_occ += occupied(st.x(), st.y() - scene.radius + 0.02, z);
		}
	EXPECT_GE(stem_occ, stem_total - 1) << stem_occ << " of " << stem_total;
	// Between the two stems and between them and the path: free.
	for (double z = 1.0; z <= 1.75; z += 0.25)
	{
		EXPECT_TRUE(known_free(4.5, 3, z)) << "z=" << z;
		EXPECT_TRUE(known_free(4.5, 1.5, z)) << "z=" << z;
	}
	// The wall is occupied, the ground too.
	EXPECT_TRUE(occupied(4.5, 8.02, 1.5));
	EXPECT_TRUE(occupied(4.5, 2, 0.02));
	EXPECT_TRUE(fs::file_size(ot) > 1000);
	std::unique_ptr<octomap::AbstractOcTree> colour(
	    octomap::AbstractOcTree::read(ot));
	ASSERT_TRUE(colour);
	EXPECT_EQ(colour->getTreeType(), "ColorOcTree");
}

// The flat-table caster finds octomap's own keys: the same file.
TEST(Octomap, DiscreteCasterFindsOctomapsKeys)
{
	std::mt19937 rng(11);
	std::uniform_real_distribution<float> u(-30.f, 30.f), z(-3.f, 8.f);
	outputs::DiscreteRayCaster caster(0.2);
	octomap::OcTree ref(0.2);
	for (int trial = 0; trial < 3; trial++)
	{
		// Points in both signs of every axis, some beyond the max range,
		// several in one voxel (one ray per voxel).
		octomap::Pointcloud cloud;
		for (int i = 0; i < 3000; i++)
		{
			const octomap::point3d p(u(rng), u(rng), z(rng));
			cloud.push_back(p);
			if (i % 10 == 0) cloud.push_back(p + octomap::point3d(0.01f, 0, 0));
		}
		const octomap::point3d origin(0.37f * trial, -1.1f, 1.5f);
		const double max_range = trial == 2 ? -1.0 : 25.0;  // -1: none
		octomap::KeySet ref_free, ref_occ;
		ref.computeDiscreteUpdate(cloud, origin, ref_free, ref_occ, max_range);
		std::vector<octomap::OcTreeKey> free, occ;
		caster.cast(cloud, origin, max_range, free, occ);
		ASSERT_EQ(free.size(), ref_free.size()) << "trial " << trial;
		ASSERT_EQ(occ.size(), ref_occ.size()) << "trial " << trial;
		for (const auto& k : free) EXPECT_TRUE(ref_free.count(k));
		for (const auto& k : occ) EXPECT_TRUE(ref_occ.count(k));
		// Tree order: depth first, i.e. lexicographic in the key bits from
		// the top level down.
		auto before =
		    [](const octomap::OcTreeKey& a, const octomap::OcTreeKey& b)
		{
			for (int bit = 15; bit >= 0; bit--)
				for (int ax = 0; ax < 3; ax++)
				{
					const int x = (a[ax] >> bit) & 1, y = (b[ax] >> bit) & 1;
					if (x != y) return x < y;
				}
			return false;
		};
		for (size_t i = 1; i < free.size(); i++)
		{
			ASSERT_TRUE(before(free[i - 1], free[i])) << i;
		}
		if (trial == 2)
		{
			EXPECT_FALSE(occ.empty());  // no max range: every end occupied
		}
	}
}

// The whole export (flat-table casting, updates along the kept tree path)
// writes the file octomap's own insertPointCloud (discretize, lazy
// evaluation) gives, beams beyond the max range included.
TEST(Octomap, WrittenFileIsOctomapsOwn)
{
	const auto dir = tempDir("octomap_same");
	const auto kfs = sceneKeyframes(Scene{});
	const auto bt = (dir / "map.bt").string();
	outputs::writeOctomap(kfs, 0.1, 12, bt);

	octomap::OcTree ref(0.1);
	for (const auto& kf : kfs)
	{
		octomap::Pointcloud cloud;
		const Eigen::Isometry3f T = kf.sensor_pose.cast<float>();
		for (const auto& p : kf.points)
		{
			const Eigen::Vector3f q = T * p;
			cloud.push_back(q.x(), q.y(), q.z());
		}
		const auto& o = kf.sensor_pose.translation();
		ref.insertPointCloud(cloud, octomap::point3d(o.x(), o.y(), o.z()), 12,
		                     true, true);
	}
	ref.updateInnerOccupancy();
	const auto ref_bt = (dir / "ref.bt").string();
	ASSERT_TRUE(ref.writeBinary(ref_bt));
	auto bytes = [](const std::string& path)
	{
		std::ifstream f(path, std::ios::binary);
		return std::string(std::istreambuf_iterator<char>(f), {});
	};
	const std::string ours = bytes(bt), theirs = bytes(ref_bt);
	EXPECT_GT(ours.size(), 10000u);
	EXPECT_TRUE(ours == theirs) << ours.size() << " vs " << theirs.size();
}

// Stops and revisits: a keyframe within octomap_keyframe_spacing_m of one
// already cast adds nothing new to the occupancy and is skipped.
TEST(Octomap, KeyframesAtPlacesAlreadyCastAreSkipped)
{
	const auto dir = tempDir("octomap_spacing");
	const Scene scene;
	const auto three = sceneKeyframes(scene);
	// The path again, 0.4 m aside, then the first place once more.
	auto kfs = three;
	for (const auto& kf : three)
	{
		auto again = kf;
		again.sensor_pose.translation().y() += 0.4;
		kfs.push_back(again);
	}
	kfs.push_back(three[0]);
	const auto bt_all = (dir / "all.bt").string(),
	           bt_spaced = (dir / "spaced.bt").string(),
	           bt_three = (dir / "three.bt").string();
	const auto all = outputs::writeOctomap(kfs, 0.1, 25, bt_all, "", 0);
	const auto spaced = outputs::writeOctomap(kfs, 0.1, 25, bt_spaced, "", 0.5);
	const auto first = outputs::writeOctomap(three, 0.1, 25, bt_three, "", 0);
	EXPECT_EQ(all.keyframes, kfs.size());
	EXPECT_EQ(all.keyframes_skipped, 0u);
	EXPECT_EQ(spaced.keyframes, three.size());
	EXPECT_EQ(spaced.keyframes_skipped, kfs.size() - three.size());
	// Exactly the tree of the first pass; the skipped views would have
	// filled more voxels (the scans' gaps), which is what is traded.
	EXPECT_EQ(spaced.occupied_leaves, first.occupied_leaves);
	EXPECT_EQ(spaced.free_leaves, first.free_leaves);
	EXPECT_EQ(fs::file_size(bt_spaced), fs::file_size(bt_three));
	EXPECT_GE(all.occupied_leaves, spaced.occupied_leaves);
	// Every keyframe farther apart than the spacing is cast.
	const auto wide = outputs::writeOctomap(kfs, 0.1, 25, bt_all, "", 0.3);
	EXPECT_EQ(wide.keyframes, kfs.size() - 1);  // only the repeated one
}

TEST(Classification, GroundVegetationAndStemClassesAndTheDtm)
{
	// Ground plane z = 0.1 x, one stem at (5, 5), a shrub and a canopy.
	std::vector<outputs::DensePoint> pts;
	const auto add = [&](double x, double y, double z)
	{
		outputs::DensePoint p;
		p.xyz = Eigen::Vector3d(x, y, z).cast<float>();
		pts.push_back(p);
	};
	for (double x = 0; x <= 10; x += 0.1)
		for (double y = 0; y <= 10; y += 0.1) add(x, y, 0.1 * x);
	for (double z = 0.2; z <= 3.5; z += 0.05)
		for (double a = 0; a < 2 * M_PI; a += 0.2)
			add(5 + 0.15 * std::cos(a), 5 + 0.15 * std::sin(a), 0.5 + z);
	for (double a = 0; a < 2 * M_PI; a += 0.3)
		add(2 + 0.2 * std::cos(a), 2, 0.2 + 0.3);
	for (double a = 0; a < 2 * M_PI; a += 0.3) add(8 + std::cos(a), 8, 0.8 + 6);
	add(1, 1, 0.1 - 2);  // below the ground: noise

	trees::TreeOptions topts;
	const auto terrain = outputs::terrainForCloud(pts, nullptr, topts);
	map::TreeRecord stem;
	stem.x = 5, stem.y = 5, stem.dbh_m = 0.3;
	outputs::OutputOptions o;
	const auto cls = outputs::classifyPoints(pts, terrain, {stem}, o);
	ASSERT_EQ(cls.size(), pts.size());
	std::map<int, int> count;
	for (size_t k = 0; k < pts.size(); k++)
	{
		const auto& p = pts[k].xyz;
		count[cls[k]]++;
		if (std::abs(p.z() - 0.1 * p.x()) < 1e-4 &&
		    std::hypot(p.x() - 5, p.y() - 5) > 0.5)
		{
			EXPECT_EQ(cls[k], outputs::kGround) << p.transpose();
		}
		if (std::hypot(p.x() - 5, p.y() - 5) < 0.2 && p.z() - 0.5 > 0.2 &&
		    p.z() - 0.5 < o.stem_max_height_m)
		{
			EXPECT_EQ(cls[k], o.stem_class) << p.transpose();
		}
	}
	EXPECT_GT(count[outputs::kLowVegetation], 10);
	EXPECT_GT(count[outputs::kHighVegetation], 10);
	EXPECT_EQ(count[outputs::kLowNoise], 1);

	const auto dir = tempDir("dtm");
	const auto grid = outputs::groundGrid(
	    pts, cls, 0.5, [](const Eigen::Vector3d& p) { return p; });
	EXPECT_GT(grid.cellsWithData(), 350u);
	for (int iy = 0; iy < grid.ny; iy++)
		for (int ix = 0; ix < grid.nx; ix++)
			if (std::isfinite(grid.at(ix, iy)))
			{
				EXPECT_NEAR(grid.at(ix, iy), 0.1 * (grid.x0 + (ix + 0.5) * 0.5),
				            0.03);
			}
	outputs::writeEsriAscii((dir / "dtm.asc").string(), grid);
	std::ifstream in(dir / "dtm.asc");
	std::string key;
	double v;
	std::map<std::string, double> hdr;
	for (int i = 0; i < 6 && in >> key >> v; i++) hdr[key] = v;
	EXPECT_EQ(hdr["ncols"], grid.nx);
	EXPECT_EQ(hdr["nrows"], grid.ny);
	EXPECT_EQ(hdr["cellsize"], 0.5);
	EXPECT_EQ(hdr["NODATA_value"], -9999);
	// First data row is the northern one: its eastern cell is the highest.
	std::vector<double> row(grid.nx);
	for (auto& x : row) in >> x;
	EXPECT_NEAR(row.back(), grid.at(grid.nx - 1, grid.ny - 1), 1e-3);
}

TEST(TreeExport, CsvGetsLatLonWhenGeoreferencedGeoJsonIsValid)
{
	const auto dir = tempDir("trees");
	std::vector<map::TreeRecord> t(2);
	t[0].id = 1, t[0].x = 10, t[0].y = 20, t[0].dbh_m = 0.25, t[0].z_ground = 1;
	t[1].id = 2, t[1].x = -5, t[1].y = 3, t[1].dbh_m = 0.4;
	outputs::GeoOptions go;
	go.mode = "utm";
	go.utm_zone = 32;
	go.utm_offset_e_m = 500000;
	go.utm_offset_n_m = 5000000;
	const auto geo = outputs::Georeference::fromOptions(go);
	outputs::writeTreesCsvGeo((dir / "geo.csv").string(), t, geo);
	outputs::writeTreesCsvGeo((dir / "local.csv").string(), t, std::nullopt);
	std::ifstream geo_csv(dir / "geo.csv");
	std::string header, row1;
	std::getline(geo_csv, header);
	std::getline(geo_csv, row1);
	EXPECT_EQ(header.rfind("id,x,y,z_ground,dbh_m,height_m", 0), 0u) << header;
	EXPECT_NE(header.find("easting_m,northing_m,lat_deg,lon_deg"),
	          std::string::npos);
	EXPECT_NE(row1.find(",500010.000,5000020.000,"), std::string::npos) << row1;
	std::ifstream local_csv(dir / "local.csv");
	std::getline(local_csv, header);
	EXPECT_EQ(header.find("lat_deg"), std::string::npos);
	EXPECT_FALSE(fs::exists(dir / "geo.csv.base"));

	outputs::writeTreesGeoJson((dir / "t.geojson").string(), t, geo);
	const auto j = readText(dir / "t.geojson");
	EXPECT_NE(j.find("\"FeatureCollection\""), std::string::npos);
	EXPECT_EQ(std::count(j.begin(), j.end(), '{'),
	          std::count(j.begin(), j.end(), '}'));
	const auto ll = geo->toLatLon({10, 20, 1});
	char lon[32];
	std::snprintf(lon, sizeof(lon), "%.6f", ll.lon_deg);
	EXPECT_NE(j.find(std::string(lon).substr(0, 8)), std::string::npos) << j;
	EXPECT_NE(j.find("\"dbh_m\": 0.4"), std::string::npos) << j;
}

// Each stem's horizontal distance from the polyline of the trajectory: the
// nearest point may lie inside a long segment, far from both its ends.
TEST(TreeExport, PathDistanceIsToThePolylineAndWrittenInCentimetres)
{
	core::Trajectory path;
	for (const auto& [x, y, z] :
	     std::vector<std::array<double, 3>>{{0, 0, 1},
	                                        {0.2, 0, 1.1},
	                                        {0.4, 0, 0.9},
	                                        {20.4, 0, 3},
	                                        {20.4, 10, 0}})
	{
		core::StampedPose s;
		s.t_s = double(path.size());
		s.pose.translation() = Eigen::Vector3d(x, y, z);
		path.push_back(s);
	}
	std::vector<map::TreeRecord> t(4);
	t[0].x = 10, t[0].y = 7.5;     // above the 20 m segment's middle: 7.5
	t[1].x = 25, t[1].y = 5;       // beside the last segment: 4.6
	t[2].x = -3, t[2].y = -4;      // behind the start: 5
	t[3].x = 20.4, t[3].y = 10.0;  // on the last pose: 0
	outputs::setPathDistances(t, path);
	EXPECT_NEAR(t[0].path_distance_m, 7.5, 1e-9);
	EXPECT_NEAR(t[1].path_distance_m, 4.6, 1e-9);
	EXPECT_NEAR(t[2].path_distance_m, 5.0, 1e-9);
	EXPECT_NEAR(t[3].path_distance_m, 0.0, 1e-9);

	std::vector<map::TreeRecord> none(1);
	outputs::setPathDistances(none, core::Trajectory{});
	EXPECT_TRUE(std::isnan(none[0].path_distance_m));

	const auto dir = tempDir("path_distance");
	none.push_back(t[1]);
	outputs::writeTreesCsvGeo((dir / "t.csv").string(), none, std::nullopt);
	std::ifstream csv(dir / "t.csv");
	std::string header, unknown, known;
	std::getline(csv, header), std::getline(csv, unknown),
	    std::getline(csv, known);
	EXPECT_EQ(header.substr(header.rfind(',') + 1), "path_distance_m");
	EXPECT_EQ(unknown.back(), ',') << unknown;  // empty: no trajectory
	EXPECT_EQ(known.substr(known.rfind(',') + 1), "4.60") << known;
	outputs::writeTreesGeoJson((dir / "t.geojson").string(), none,
	                           std::nullopt);
	const auto j = readText(dir / "t.geojson");
	EXPECT_EQ(std::count(j.begin(), j.end(), '{'),
	          std::count(j.begin(), j.end(), '}'));
	EXPECT_NE(j.find("\"path_distance_m\": 4.6"), std::string::npos) << j;
	EXPECT_EQ(j.find("path_distance_m"), j.rfind("path_distance_m"))
	    << "only the stem with a distance has the property";
}

TEST(Report, StandTableFigures)
{
	std::vector<map::TreeRecord> t(2);
	t[0].dbh_m = 0.2;
	t[1].dbh_m = 0.4;
	const auto s = outputs::standTable(t, 5000);  // 0.5 ha
	EXPECT_EQ(s.stems, 2u);
	EXPECT_DOUBLE_EQ(s.stems_per_ha, 4);
	EXPECT_NEAR(s.basal_area_m2_per_ha, 2 * M_PI / 4 * (0.04 + 0.16), 1e-12);
	EXPECT_DOUBLE_EQ(s.mean_dbh_m, 0.3);
	EXPECT_NEAR(s.quadratic_mean_dbh_m, std::sqrt(0.1), 1e-12);
	ASSERT_EQ(s.classes.size(), 5u);  // 0-10 ... 40-50 cm
	EXPECT_EQ(s.classes[2].stems, 1u);
	EXPECT_EQ(s.classes[4].stems, 1u);
	EXPECT_EQ(s.classes[3].stems, 0u);
}

TEST(Report, GnssCoverageSharesOfThePath)
{
	core::Trajectory tr;
	for (int i = 0; i <= 100; i++)
	{
		core::StampedPose p;
		p.t_s = i;
		p.pose.translation() = Eigen::Vector3d(i, 0, 0);
		tr.push_back(p);
	}
	std::vector<outputs::GnssEpoch> g;
	for (int i = 0; i <= 50; i++) g.push_back({double(i), 4, 0, 0, 0});
	for (int i = 51; i <= 75; i++) g.push_back({double(i), 1, 0, 0, 0});
	const auto c = outputs::gnssCoverage(tr, g, 1.5);
	std::map<int, double> m(c.begin(), c.end());
	EXPECT_NEAR(m[4], 0.50, 0.011);
	EXPECT_NEAR(m[1], 0.25, 0.011);
	EXPECT_NEAR(m[-1], 0.24, 0.011);  // no epoch within 1.5 s after t=76.5
}
