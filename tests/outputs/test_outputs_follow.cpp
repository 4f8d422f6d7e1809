// Loop corrections reach the dense map (doc/backend.md "Outputs and what
// follows the corrections"): DenseMap::transformPoints moves every point
// with its own correction, in memory or with tiles on disk (in place); the
// DTM and map.las written after it are the moved ones. The map->ENU transform
// the back-end estimates places the georeferenced outputs (Georeference with
// map_to_enu_*).
#include "test_files.h"

#include <forest_slam/io/las.h>
#include <forest_slam/outputs/dense_map.h>
#include <forest_slam/outputs/georeference.h>
#include <forest_slam/outputs/run_collector.h>
#include <forest_slam/outputs/write_outputs.h>
#include <gtest/gtest.h>

#include <GeographicLib/LocalCartesian.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <stdexcept>
#include <tuple>

using namespace forest_slam;

namespace
{
/** The correction of the test: points before t = 50 s (a drifted first
 * pass) turn 3 deg about z at (10, 0) and rise 0.2 m; later ones stay. */
Eigen::Isometry3f correctionAt(float t_s)
{
	Eigen::Isometry3f C = Eigen::Isometry3f::Identity();
	if (t_s >= 50) return C;
	Eigen::Isometry3f P = Eigen::Isometry3f::Identity();
	P.translation() = Eigen::Vector3f(10, 0, 0);
	Eigen::Isometry3f R = Eigen::Isometry3f::Identity();
	R.linear() =
	    Eigen::AngleAxisf(3.0f * float(M_PI) / 180, Eigen::Vector3f::UnitZ())
	        .toRotationMatrix();
	C = P * R * P.inverse();
	C.translation().z() += 0.2f;
	return C;
}

std::set<std::tuple<float, float, float, float, uint16_t>> asSet(
    const std::vector<outputs::DensePoint>& pts)
{
	std::set<std::tuple<float, float, float, float, uint16_t>> s;
	for (const auto& p : pts)
		s.emplace(p.xyz.x(), p.xyz.y(), p.xyz.z(), p.t_s, p.intensity);
	return s;
}
}  // namespace

TEST(DenseMapFollow, EveryPointMovesWithItsOwnCorrectionInPlace)
{
	// A sensor walking out 100 m (t < 50 s) and back; 5 m tiles spilled
	// beyond 20 m in one map, all in memory in the other.
	outputs::DenseMap mem(0.05), tiled(0.05, 5.0);
	auto spill = std::make_shared<core::SpillFile>();
	std::mt19937 rng(5);
	std::uniform_real_distribution<float> u(-12, 12);
	uint16_t n = 0;
	std::vector<outputs::DensePoint> added;  // kept, in the order kept
	float t = 0;
	auto scan = [&](float sx)
	{
		for (int k = 0; k < 3000; k++)
		{
			outputs::DensePoint p;
			p.xyz = {sx + u(rng), u(rng), u(rng) / 10};
			p.t_s = t;
			p.intensity = n++;
			const bool kept = mem.add(p);
			EXPECT_EQ(kept, tiled.add(p));
			if (kept) added.push_back(p);
		}
		tiled.spillFar(Eigen::Vector2d(sx, 0), 20.0, spill);
		t += 1;
	};
	for (float x = 0; x < 100; x += 2) scan(x);
	for (float x = 100; x > 0; x -= 2) scan(x);
	ASSERT_GT(tiled.tilesSpilled(), 0u);

	// What the correction must give: the same points, each moved by its
	// own correction (not thinned to one per voxel again: a shift by a
	// fraction of a voxel would drop a good part of a dense surface).
	std::vector<outputs::DensePoint> want = added;
	for (auto& p : want) p.xyz = correctionAt(p.t_s) * p.xyz;
	const auto move = [](outputs::DensePoint& p)
	{ p.xyz = correctionAt(p.t_s) * p.xyz; };
	const size_t spilled_bytes = tiled.spilledBytes();
	const uint64_t file_bytes = spill->size();
	mem.transformPoints(move);
	tiled.transformPoints(move);
	EXPECT_EQ(mem.size(), added.size());
	EXPECT_EQ(tiled.size(), added.size());
	EXPECT_TRUE(asSet(mem.points()) == asSet(want));
	EXPECT_TRUE(asSet(tiled.points()) == asSet(want));
	// Spilled tiles were moved in place: no more disk.
	EXPECT_GT(tiled.tilesSpilled(), 0u);
	EXPECT_EQ(tiled.spilledBytes(), spilled_bytes);
	EXPECT_EQ(spill->size(), file_bytes);
	size_t moved = 0;
	for (const auto& p : mem.points()) moved += p.t_s < 50;
	EXPECT_GT(moved, 10000u);
	// The map is final: a point added after the correction would be kept
	// or dropped against voxels that no longer hold their points.
	EXPECT_THROW(mem.add(outputs::DensePoint{}), std::logic_error);
}

TEST(RunCollector, CollectsOnlyWhatTheFilesAskedForRead)
{
	// A ring of returns over 30 scans, 1 m apart: keyframes and the dense
	// map when files read them, nothing but the count otherwise.
	auto run = [](const outputs::OutputOptions& o)
	{
		outputs::RunCollector col(o);
		for (int k = 0; k < 30; k++)
		{
			core::ScanPoints s;
			s.stamp_s = 1000 + 0.1 * k;
			s.sweep_s = 0.1;
			std::vector<Eigen::Vector3f> deskewed;
			for (int i = 0; i < 360; i++)
			{
				core::ScanPoint p;
				p.x = 5 * std::cos(i * M_PI / 180);
				p.y = 5 * std::sin(i * M_PI / 180);
				p.z = -1;
				p.range_m = std::sqrt(26.f);
				s.points.push_back(p);
				deskewed.emplace_back(p.x, p.y, p.z);
			}
			Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
			T.translation().x() = k;
			col.addScan(s, core::StampedPose{s.stamp_s, T}, deskewed, nullptr);
		}
		return std::make_tuple(col.scans(), col.keyframes().size(),
		                       col.dense().size());
	};
	outputs::OutputOptions all;
	all.spill_to_disk = false;
	const auto [n_all, kf_all, dense_all] = run(all);
	EXPECT_EQ(n_all, 30u);
	EXPECT_EQ(kf_all, 30u);  // every scan 1 m on
	EXPECT_GT(dense_all, 30u * 300);

	outputs::OutputOptions none = all;
	none.las = none.dtm_asc = none.report_html = false;
	none.keyframes_simplemap = none.octomap_bt = false;
	// Trees from the tree layer only: the dense map is not read for them.
	none.detect_trees_if_empty = false;
	ASSERT_FALSE(none.needsDenseMap());
	ASSERT_FALSE(none.needsKeyframeClouds());
	const auto [n_none, kf_none, dense_none] = run(none);
	EXPECT_EQ(n_none, 30u);
	EXPECT_EQ(kf_none, 0u);
	EXPECT_EQ(dense_none, 0u);

	outputs::OutputOptions map_bt = none;  // keyframes, no dense map
	map_bt.octomap_bt = true;
	const auto [n_bt, kf_bt, dense_bt] = run(map_bt);
	EXPECT_EQ(kf_bt, 30u);
	EXPECT_EQ(dense_bt, 0u);

	outputs::OutputOptions pcd = none;  // dense map, no keyframes
	pcd.pcd = true;
	const auto [n_pcd, kf_pcd, dense_pcd] = run(pcd);
	EXPECT_EQ(kf_pcd, 0u);
	EXPECT_EQ(dense_pcd, dense_all);

	outputs::OutputOptions trees = none;  // trees detected on the dense map
	trees.detect_trees_if_empty = true;
	EXPECT_TRUE(trees.needsDenseMap());
}

TEST(DenseMapFollow, LasAndDtmWrittenAfterACorrectionAreTheMovedGround)
{
	// Flat ground z = -1.5 under a sensor at rest, collected twice; one
	// collector's dense map is then moved 2 m east and 0.5 m up. Its
	// map.las and dtm.asc are the first ones moved by that much.
	const auto dir = test_support::freshTempDir("follow_dtm");
	outputs::OutputOptions o;
	o.trajectory_kitti = o.keyframes_simplemap = o.forest_map = false;
	o.octomap_bt = o.trees_csv = o.trees_geojson = o.report_html = false;
	o.detect_trees_if_empty = false;
	o.spill_to_disk = false;
	auto collect = [&](outputs::RunCollector& col)
	{
		core::ScanPoints s;
		s.stamp_s = 1000;
		s.sweep_s = 0.1;
		for (int i = 0; i < 200; i++)
			for (int j = 0; j < 200; j++)
			{
				core::ScanPoint p;
				p.x = -10 + 0.1f * i + 0.013f;
				p.y = -10 + 0.1f * j + 0.017f;
				p.z = -1.5f;
				p.range_m = std::sqrt(p.x * p.x + p.y * p.y + p.z * p.z);
				p.intensity = 100;
				s.points.push_back(p);
			}
		col.addScan(s, core::StampedPose{1000, Eigen::Isometry3d::Identity()},
		            [](double, Eigen::Isometry3d&) { return false; });
	};
	outputs::RunCollector a(o), b(o);
	collect(a);
	collect(b);
	b.transformDense([](outputs::DensePoint& p)
	                 { p.xyz += Eigen::Vector3f(2, 0, 0.5f); });
	core::Trajectory traj{{1000, Eigen::Isometry3d::Identity()}};
	const map::CForestMap m;
	const outputs::GeoOptions geo;
	const trees::TreeOptions topt;
	std::filesystem::create_directories(dir / "a");
	std::filesystem::create_directories(dir / "b");
	outputs::writeRunOutputs({traj, m, a, o, geo, topt, {}},
	                         (dir / "a").string());
	outputs::writeRunOutputs({traj, m, b, o, geo, topt, {}},
	                         (dir / "b").string());
	const auto la = io::readLas((dir / "a/map.las").string());
	const auto lb = io::readLas((dir / "b/map.las").string());
	ASSERT_GT(la.size(), 10000u);
	ASSERT_EQ(la.size(), lb.size());
	std::multiset<std::tuple<long, long, long, int>> sa, sb;
	for (size_t k = 0; k < la.size(); k++)
	{
		const Eigen::Vector3d q = la.xyz[k] + Eigen::Vector3d(2, 0, 0.5);
		sa.emplace(std::lround(q.x() * 1000), std::lround(q.y() * 1000),
		           std::lround(q.z() * 1000), la.classification[k]);
		sb.emplace(std::lround(lb.xyz[k].x() * 1000),
		           std::lround(lb.xyz[k].y() * 1000),
		           std::lround(lb.xyz[k].z() * 1000), lb.classification[k]);
	}
	EXPECT_TRUE(sa == sb);
	auto dtm = [](const std::filesystem::path& f)
	{
		std::ifstream in(f);
		std::map<std::string, double> hdr;
		std::string key;
		double v;
		for (int i = 0; i < 6 && in >> key >> v; i++) hdr[key] = v;
		std::vector<double> cells;
		while (in >> v)
			if (v != hdr["NODATA_value"] && v != -9999) cells.push_back(v);
		return std::make_pair(hdr, cells);
	};
	const auto [ha, ca] = dtm(dir / "a/dtm.asc");
	const auto [hb, cb] = dtm(dir / "b/dtm.asc");
	ASSERT_GT(ca.size(), 100u);
	ASSERT_EQ(ca.size(), cb.size());
	EXPECT_NEAR(hb.at("xllcorner") - ha.at("xllcorner"), 2.0, 1e-6);
	EXPECT_NEAR(hb.at("yllcorner"), ha.at("yllcorner"), 1e-6);
	for (size_t k = 0; k < ca.size(); k++)
	{
		EXPECT_NEAR(ca[k], -1.5, 0.01);
		EXPECT_NEAR(cb[k], -1.0, 0.01);
	}
}

TEST(Georeference, EstimatedMapToEnuTransformPlacesTheMapFrame)
{
	// The back-end's estimate: map -> ENU of the first fix is a 30 deg
	// turn and a shift; a map point must land where that ENU point does
	// with the map frame taken as ENU.
	outputs::GeoOptions g;
	g.mode = "enu_origin";
	g.origin_lat_deg = 48.1;
	g.origin_lon_deg = 11.5;
	g.origin_alt_m = 520;
	const auto plain = outputs::Georeference::fromOptions(g);
	g.map_to_enu_yaw_rad = 30 * M_PI / 180;
	g.map_to_enu_x_m = 5;
	g.map_to_enu_y_m = -3;
	g.map_to_enu_z_m = 1.5;
	const auto est = outputs::Georeference::fromOptions(g);
	ASSERT_TRUE(plain && est);
	const Eigen::Vector3d p(40, 10, -2);
	const Eigen::Vector3d enu(
	    std::cos(M_PI / 6) * 40 - std::sin(M_PI / 6) * 10 + 5,
	    std::sin(M_PI / 6) * 40 + std::cos(M_PI / 6) * 10 - 3, -0.5);
	EXPECT_LT((est->toEnu(p) - enu).norm(), 1e-9);
	EXPECT_LT((est->toProjected(p) - plain->toProjected(enu)).norm(), 1e-6);
	const auto a = est->toLatLon(p), b = plain->toLatLon(enu);
	EXPECT_NEAR(a.lat_deg, b.lat_deg, 1e-10);
	EXPECT_NEAR(a.lon_deg, b.lon_deg, 1e-10);
	EXPECT_NEAR(a.alt_m, b.alt_m, 1e-6);
	// And the ENU point is where GeographicLib puts it.
	GeographicLib::LocalCartesian lc(48.1, 11.5, 520);
	double lat, lon, h;
	lc.Reverse(enu.x(), enu.y(), enu.z(), lat, lon, h);
	EXPECT_NEAR(a.lat_deg, lat, 1e-10);
	EXPECT_NEAR(a.lon_deg, lon, 1e-10);
}
