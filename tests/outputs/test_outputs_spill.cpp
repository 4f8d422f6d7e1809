// Memory bounded by area (doc/performance.md): dense-map tiles and keyframe
// clouds moved to the spill file give the same points and files as keeping
// everything in memory.
#include "test_files.h"

#include <forest_slam/outputs/dense_map.h>
#include <forest_slam/outputs/run_collector.h>
#include <forest_slam/outputs/simplemap_export.h>
#include <gtest/gtest.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CObservationPointCloud.h>

#include <algorithm>
#include <random>
#include <tuple>

using namespace forest_slam;

namespace
{
std::vector<std::tuple<float, float, float, float, uint16_t>> sorted(
    const std::vector<outputs::DensePoint>& pts)
{
	std::vector<std::tuple<float, float, float, float, uint16_t>> v;
	for (const auto& p : pts)
		v.emplace_back(p.xyz.x(), p.xyz.y(), p.xyz.z(), p.t_s, p.intensity);
	std::sort(v.begin(), v.end());
	return v;
}
}  // namespace

TEST(DenseMapSpill, TilesOnDiskKeepTheSamePointsAsOneTableInMemory)
{
	// A sensor walking out 200 m and back: returns within 15 m of it, 5 m
	// tiles, tiles beyond 20 m spilled after every "scan".
	outputs::DenseMap all(0.05), tiled(0.05, 5.0);
	auto spill = std::make_shared<core::SpillFile>();
	std::mt19937 rng(3);
	std::uniform_real_distribution<float> u(-15, 15);
	size_t most_in_memory = 0, spilled_max = 0;
	uint16_t n = 0;
	auto scan = [&](float sx)
	{
		for (int k = 0; k < 4000; k++)
		{
			outputs::DensePoint p;
			p.xyz = {sx + u(rng), u(rng), u(rng) / 10};
			p.t_s = sx;
			p.intensity = n++;
			EXPECT_EQ(all.add(p), tiled.add(p));
		}
		tiled.spillFar(Eigen::Vector2d(sx, 0), 20.0, spill);
		most_in_memory = std::max(most_in_memory, tiled.memoryBytes());
		spilled_max = std::max(spilled_max, tiled.spilledBytes());
	};
	for (float x = 0; x <= 200; x += 2) scan(x);
	for (float x = 200; x >= -10; x -= 2) scan(x);
	EXPECT_EQ(all.size(), tiled.size());
	EXPECT_GT(spilled_max, 0u);
	EXPECT_GT(tiled.tilesSpilled(), 0u);
	// Memory stays that of the tiles near the sensor.
	EXPECT_LT(most_in_memory, all.memoryBytes() / 3);
	EXPECT_EQ(sorted(all.points()), sorted(tiled.points()));
	size_t seen = 0;
	tiled.forEachTile([&](const std::vector<outputs::DensePoint>& pts)
	                  { seen += pts.size(); });
	EXPECT_EQ(seen, tiled.size());
}

TEST(DenseMapSpill, RevisitedTilesKeepTheirPointsInOrderAndOnDisk)
{
	// Out and back twice over the same 60 m: every tile is spilled and
	// revisited. Against the same tiles never spilled: the same points in
	// the same order (chunk after chunk), the same after a move, and a
	// revisited tile holds only its voxel table and its new points.
	outputs::DenseMap kept(0.05, 5.0), tiled(0.05, 5.0);
	auto spill = std::make_shared<core::SpillFile>();
	std::mt19937 rng(11);
	std::uniform_real_distribution<float> u(-8, 8);
	uint16_t n = 0;
	size_t revisit_memory = 0, first_memory = 0, after_first_lap = 0;
	// Points on a 10 cm lattice of a ground plane: the first lap sees most
	// of the voxels, the second one few new ones (as on a real revisit).
	const auto q = [](float v) { return std::round(v * 10) / 10 + 0.01f; };
	auto scan = [&](float sx)
	{
		for (int k = 0; k < 3000; k++)
		{
			outputs::DensePoint p;
			p.xyz = {q(sx + u(rng)), q(u(rng)), 0.01f};
			p.t_s = sx;
			p.intensity = n++;
			EXPECT_EQ(kept.add(p), tiled.add(p));
		}
		tiled.spillFar(Eigen::Vector2d(sx, 0), 10.0, spill);
	};
	for (int lap = 0; lap < 2; lap++)
	{
		for (float x = 0; x <= 60; x += 1) scan(x);
		if (lap == 0) first_memory = tiled.memoryBytes();
		for (float x = 60; x >= 0; x -= 1) scan(x);
		if (lap == 0) after_first_lap = tiled.size();
		if (lap == 1) revisit_memory = tiled.memoryBytes();
	}
	ASSERT_EQ(kept.size(), tiled.size());
	EXPECT_GT(tiled.spilledBytes(), 0u);
	// Near the sensor: tables and a lap's new points, far below the points
	// themselves (20 bytes each, plus their table) when everything stays.
	// The revisited tiles near the end (x = 0) hold the points of the
	// second lap only; the first lap's stay on disk.
	size_t near = 0;
	for (const auto& p : kept.points()) near += p.xyz.x() < 15 ? 1 : 0;
	EXPECT_GT(tiled.pointsInMemory(), 0u);
	EXPECT_LE(tiled.pointsInMemory(), kept.size() - after_first_lap);
	EXPECT_LT(tiled.pointsInMemory(), near / 4);
	EXPECT_LT(revisit_memory, near * (sizeof(outputs::DensePoint) + 24));
	EXPECT_GT(first_memory, 0u);
	auto same = [&]()
	{
		const auto a = kept.points(), b = tiled.points();
		ASSERT_EQ(a.size(), b.size());
		for (size_t i = 0; i < a.size(); i++)
		{
			ASSERT_EQ(a[i].xyz, b[i].xyz) << i;
			ASSERT_EQ(a[i].intensity, b[i].intensity) << i;
		}
	};
	same();
	const auto move = [](outputs::DensePoint& p)
	{ p.xyz += Eigen::Vector3f(0.3f, -0.1f, 0.02f * p.t_s); };
	kept.transformPoints(move);
	tiled.transformPoints(move);
	same();
}

TEST(DenseMapSpill, VoxelsOnTileBordersAreNotDuplicated)
{
	// Points straddling the tile edge x = 5 m (and negative tiles): one per
	// voxel whatever tile the float coordinates round into.
	outputs::DenseMap all(0.05), tiled(0.05, 5.0);
	auto spill = std::make_shared<core::SpillFile>();
	// First lookup in tile (-1, -1): its key is all ones.
	tiled.prefetch(Eigen::Vector3f(-0.5f, -0.5f, 0));
	const auto* first = tiled.claim(Eigen::Vector3f(-0.5f, -0.5f, 0));
	ASSERT_NE(first, nullptr);
	EXPECT_EQ(first->xyz, Eigen::Vector3f(-0.5f, -0.5f, 0));
	ASSERT_NE(all.claim(Eigen::Vector3f(-0.5f, -0.5f, 0)), nullptr);
	for (int i = -2000; i <= 2000; i++)
		for (float base : {5.0f, -5.0f, 0.0f, -10.0f})
		{
			outputs::DensePoint p;
			p.xyz = {base + i * 1e-5f, 0.01f * (i % 7), 0};
			EXPECT_EQ(all.add(p), tiled.add(p)) << p.xyz.transpose();
			if (i % 500 == 0)
				tiled.spillFar(Eigen::Vector2d(1000, 1000), 1.0, spill);
		}
	EXPECT_EQ(all.size(), tiled.size());
}

TEST(KeyframeSpill, SimpleMapStreamedFromDiskEqualsTheInMemoryOne)
{
	const auto dir = test_support::freshTempDir("kfspill");
	outputs::Keyframes kfs;
	std::mt19937 rng(5);
	std::uniform_real_distribution<float> u(-20, 20);
	for (int k = 0; k < 5; k++)
	{
		outputs::KeyframeCloud kf;
		kf.t_s = 1700000000.0 + k;
		kf.sensor_pose.translation() = Eigen::Vector3d(k, 0.5 * k, 0.1);
		kf.sensor_pose.linear() =
		    Eigen::AngleAxisd(0.1 * k, Eigen::Vector3d::UnitZ())
		        .toRotationMatrix();
		for (int i = 0; i < 1000 + 100 * k; i++)
			kf.points.emplace_back(u(rng), u(rng), u(rng) / 4);
		kfs.push_back(kf);
	}
	const auto a = (dir / "a.simplemap").string(),
	           b = (dir / "b.simplemap").string();
	outputs::writeSimpleMap(a, outputs::toSimpleMap(kfs));
	size_t loads = 0;
	outputs::writeSimpleMap(b, kfs,
	                        [&](size_t i)
	                        {
		                        loads++;
		                        return kfs[i].points;
	                        });
	EXPECT_GE(loads, kfs.size());
	mrpt::maps::CSimpleMap sa, sb;
	ASSERT_TRUE(sa.loadFromFile(a));
	ASSERT_TRUE(sb.loadFromFile(b)) << "streamed simplemap not readable";
	ASSERT_EQ(sa.size(), sb.size());
	for (size_t i = 0; i < sa.size(); i++)
	{
		mrpt::poses::CPose3DPDF::Ptr pa, pb;
		mrpt::obs::CSensoryFrame::Ptr fa, fb;
		sa.get(i, pa, fa);
		sb.get(i, pb, fb);
		EXPECT_EQ(pa->getMeanVal().asString(), pb->getMeanVal().asString());
		auto oa =
		    fa->getObservationByClass<mrpt::obs::CObservationPointCloud>();
		auto ob =
		    fb->getObservationByClass<mrpt::obs::CObservationPointCloud>();
		ASSERT_TRUE(oa && ob);
		EXPECT_EQ(oa->timestamp, ob->timestamp);
		ASSERT_EQ(oa->pointcloud->size(), ob->pointcloud->size());
		ASSERT_EQ(oa->pointcloud->size(), kfs[i].points.size());
		for (size_t k = 0; k < kfs[i].points.size(); k += 97)
		{
			float xa, ya, za, xb, yb, zb;
			oa->pointcloud->getPoint(k, xa, ya, za);
			ob->pointcloud->getPoint(k, xb, yb, zb);
			EXPECT_EQ(xa, xb);
			EXPECT_EQ(ya, yb);
			EXPECT_EQ(za, zb);
		}
	}
}

TEST(KeyframeSpill, BadSpillDirStopsBeforeTheRun)
{
	outputs::OutputOptions o;
	o.spill_dir = "/nonexistent/spill-here";
	EXPECT_THROW(outputs::RunCollector c(o), std::runtime_error);
	o.spill_to_disk = false;
	EXPECT_NO_THROW(outputs::RunCollector c(o));
}

TEST(DenseMapSpill, TileBeyondItsHeightWindowKeepsEveryVoxelOnce)
{
	// A tile's points 1.7 km apart in z (its table once held tile-local
	// keys within a z window, rebuilt on global keys beyond it; its blocks
	// now have global keys): every voxel is kept once, before and after a
	// spill.
	outputs::DenseMap untiled(0.05), tiled(0.05, 20.0);
	auto spill = std::make_shared<core::SpillFile>();
	std::vector<Eigen::Vector3f> pts;
	for (int k = 0; k < 300; k++)
		pts.emplace_back(1.025f + 0.05f * (k % 10), 2.025f + 0.05f * (k / 10),
		                 0.025f);
	for (int k = 0; k < 200; k++)
		pts.emplace_back(3.025f + 0.05f * (k % 10), 2.025f,
		                 900.025f + 0.05f * k);
	for (int k = 0; k < 200; k++)
		pts.emplace_back(5.025f, 7.025f + 0.05f * k, -799.975f);
	size_t kept = 0;
	for (int pass = 0; pass < 2; pass++)
	{
		for (const auto& p : pts)
		{
			outputs::DensePoint d;
			d.xyz = p;
			const bool a = untiled.add(d);
			EXPECT_EQ(a, tiled.add(d));
			kept += a;
			// The same voxel again (points at voxel centres), a fraction
			// of a voxel aside.
			d.xyz = p + Eigen::Vector3f(0.001f, 0.001f, 0.001f);
			EXPECT_FALSE(tiled.add(d));
		}
		// Far away: the tile goes to disk, the next pass reads it back.
		EXPECT_EQ(tiled.spillFar(Eigen::Vector2d(500, 500), 50, spill), 1u);
	}
	EXPECT_EQ(kept, 700u);
	EXPECT_EQ(tiled.size(), 700u);
	EXPECT_EQ(sorted(untiled.points()), sorted(tiled.points()));
}

TEST(DenseMapSpill, RevisitedTileCostsItsBlockTableOnly)
{
	// 100,000 voxels of one 20 m tile on disk, then one point into it:
	// only its table of 4 x 4 x 4-voxel blocks comes back (a 300 x 300
	// voxel layer and a part of the next, in the same 75 x 75 blocks, and
	// the new point's: 5,626 blocks at 3 in 4 at most, 2^13 slots of 16
	// bytes).
	outputs::DenseMap m(0.05, 20.0);
	auto spill = std::make_shared<core::SpillFile>();
	for (int i = 0; i < 100000; i++)
	{
		outputs::DensePoint d;
		d.xyz = {0.05f * (i % 300) + 0.01f, 0.05f * (i / 300 % 300) + 0.01f,
		         0.05f * (i / 90000) + 0.01f};
		ASSERT_TRUE(m.add(d));
	}
	ASSERT_EQ(m.spillFar(Eigen::Vector2d(500, 500), 50, spill), 1u);
	EXPECT_LT(m.memoryBytes(), 4096u);
	outputs::DensePoint d;
	d.xyz = {19.9f, 19.9f, 3.0f};
	ASSERT_TRUE(m.add(d));
	EXPECT_EQ(m.tilesSpilled(), 0u);
	EXPECT_GE(m.memoryBytes(), (size_t(1) << 13) * 16);
	EXPECT_LT(m.memoryBytes(), (size_t(1) << 13) * 16 + 4096);
	// The reloaded table still knows every voxel on disk.
	d.xyz = {0.05f * 17 + 0.02f, 0.05f * 33 + 0.02f, 0.02f};
	EXPECT_FALSE(m.add(d));
	EXPECT_EQ(m.size(), 100001u);
}

TEST(DenseMapSpill, EveryVoxelOfBlocksAcrossTileBordersKeptOnce)
{
	// Tiles of 23 voxels (1.15 m), not a multiple of the 4-voxel blocks:
	// blocks straddle tile borders, on both sides of the origin. Every
	// voxel of a 60 x 60 x 8 box (16 tiles) is claimed in a shuffled
	// order, then
	// again (all taken), then again after the tiles went to disk.
	outputs::DenseMap m(0.05, 1.15);
	auto spill = std::make_shared<core::SpillFile>();
	std::vector<Eigen::Vector3f> centres;
	for (int i = -30; i < 30; i++)
		for (int j = -30; j < 30; j++)
			for (int k = -4; k < 4; k++)
				centres.emplace_back(0.05f * i + 0.025f, 0.05f * j + 0.025f,
				                     0.05f * k + 0.025f);
	std::mt19937 rng(3);
	std::shuffle(centres.begin(), centres.end(), rng);
	for (int pass = 0; pass < 3; pass++)
	{
		size_t kept = 0;
		for (const auto& c : centres)
		{
			outputs::DensePoint d;
			d.xyz = c + Eigen::Vector3f(0.01f, -0.01f, 0.005f) * float(pass);
			kept += m.add(d);
		}
		EXPECT_EQ(kept, pass == 0 ? centres.size() : 0u) << pass;
		if (pass == 1)
		{
			EXPECT_EQ(m.spillFar(Eigen::Vector2d(500, 500), 50, spill), 16u);
		}
	}
	EXPECT_EQ(m.size(), centres.size());
	EXPECT_EQ(m.tilesSpilled(), 0u);
}
