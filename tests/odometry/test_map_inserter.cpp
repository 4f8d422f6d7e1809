// MapInserter: the CForestMap filled on a worker thread is the map filled on
// the caller's thread, scan for scan, and a reader that flushes sees every
// queued scan.
#include <forest_slam/odometry/map_inserter.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <random>

using namespace forest_slam;

namespace
{
struct Scan
{
	std::vector<Eigen::Vector3f> edges, planar;
	Eigen::Isometry3d pose;
};

std::vector<Scan> randomScans(int n)
{
	std::mt19937 rng(7);
	std::uniform_real_distribution<float> U(-15, 15);
	std::vector<Scan> scans(n);
	for (int s = 0; s < n; s++)
	{
		for (int i = 0; i < 2000; i++)
			scans[s].planar.emplace_back(U(rng), U(rng), U(rng) * 0.1f);
		for (int i = 0; i < 500; i++)
			scans[s].edges.emplace_back(U(rng), U(rng), U(rng));
		scans[s].pose = Eigen::Isometry3d::Identity();
		scans[s].pose.translation() = Eigen::Vector3d(0.7 * s, 0.1 * s, 0);
		scans[s].pose.linear() =
		    Eigen::AngleAxisd(0.05 * s, Eigen::Vector3d::UnitZ())
		        .toRotationMatrix();
	}
	return scans;
}

/** Sorted centroids of every voxel: (x, y, z, 0 = edge / 1 = planar). */
std::vector<std::array<float, 4>> contents(const map::CForestMap& m)
{
	std::vector<std::array<float, 4>> out;
	for (const auto& [k, sm] : m.submaps())
	{
		std::vector<Eigen::Vector3f> e, p;
		sm.edge.appendCentroids(e);
		sm.planar.appendCentroids(p);
		for (const auto& v : e) out.push_back({v.x(), v.y(), v.z(), 0.f});
		for (const auto& v : p) out.push_back({v.x(), v.y(), v.z(), 1.f});
	}
	std::sort(out.begin(), out.end());
	return out;
}
}  // namespace

TEST(MapInserter, WorkerThreadFillsTheSameMap)
{
	const auto scans = randomScans(12);
	map::CForestMap sync_map, async_map;
	{
		odometry::MapInserter direct(sync_map, 0);
		for (const auto& s : scans) direct.push(s.edges, s.planar, s.pose);
	}
	odometry::MapInserter worker(async_map, 2);  // the producer must block
	for (const auto& s : scans) worker.push(s.edges, s.planar, s.pose);
	worker.flush();
	ASSERT_GT(sync_map.edgePointCount(), 1000u);
	EXPECT_EQ(async_map.edgePointCount(), sync_map.edgePointCount());
	EXPECT_EQ(async_map.planarPointCount(), sync_map.planarPointCount());
	EXPECT_EQ(contents(async_map), contents(sync_map));
}

TEST(MapInserter, DestructorFinishesQueuedScans)
{
	const auto scans = randomScans(6);
	map::CForestMap expected, m;
	for (const auto& s : scans)
		expected.insertFeatures(s.edges, s.planar, s.pose);
	{
		odometry::MapInserter worker(m, 8);
		for (const auto& s : scans) worker.push(s.edges, s.planar, s.pose);
	}
	EXPECT_EQ(m.edgePointCount(), expected.edgePointCount());
	EXPECT_EQ(m.planarPointCount(), expected.planarPointCount());
}
