#include <forest_slam/cluster/hierarchical_kmeans.h>
#include <forest_slam/core/config.h>
#include <gtest/gtest.h>

#include <map>
#include <random>
#include <set>

using namespace forest_slam;

namespace
{
/** Stems (vertical cylinders r=0.15 m, 0.5..4 m high) at least 2 m apart,
 * each with its own id, plus a few isolated noise points. */
struct Stems
{
	std::vector<Eigen::Vector3f> pts;
	std::vector<int> owner;
};
Stems makeStems(uint32_t seed, int n_stems, int pts_per_stem)
{
	std::mt19937 rng(seed);
	std::uniform_real_distribution<double> U(0, 1);
	Stems s;
	for (int t = 0; t < n_stems; t++)
	{
		const double cx = 3.0 * (t % 5) + 5, cy = 3.0 * (t / 5) - 6;
		for (int k = 0; k < pts_per_stem; k++)
		{
			const double a = M_PI * (0.5 + U(rng));	 // side facing the sensor
			s.pts.emplace_back(cx + 0.15 * std::cos(a), cy + 0.15 * std::sin(a),
							   0.5 + 3.5 * U(rng));
			s.owner.push_back(t);
		}
	}
	return s;
}
}  // namespace

TEST(HierarchicalKMeans, ClustersAreSmallAndNeverMixSeparatedStems)
{
	const auto s = makeStems(1, 15, 600);
	cluster::ClusterOptions o;
	o.max_cluster_points = 80;
	const auto L = cluster::hierarchicalKMeans(s.pts, o);
	ASSERT_EQ(L.cluster.size(), s.pts.size());
	std::map<int, std::set<int>> owners;
	for (size_t i = 0; i < s.pts.size(); i++)
	{
		ASSERT_GE(L.cluster[i], 0);
		owners[L.cluster[i]].insert(s.owner[i]);
		EXPECT_EQ(L.cluster_size[i], L.sizes[L.cluster[i]]);
		EXPECT_NEAR(L.range_m[i], s.pts[i].norm(), 1e-5);
	}
	for (const auto& [c, who] : owners) EXPECT_EQ(who.size(), 1u) << "cluster " << c;
	size_t total = 0;
	for (auto n : L.sizes)
	{
		// Leaves hold <= sigma; merged small clusters may add up to
		// min_cluster_points-1 points each, so allow some slack.
		EXPECT_LE(n, 2u * o.max_cluster_points);
		EXPECT_GE(n, static_cast<uint32_t>(o.min_cluster_points));
		total += n;
	}
	EXPECT_EQ(total, s.pts.size());
	EXPECT_GE(L.clusterCount(), s.pts.size() / o.max_cluster_points);
}

TEST(HierarchicalKMeans, DeterministicAndOrderOfCentroidsStable)
{
	const auto s = makeStems(2, 8, 400);
	const auto a = cluster::hierarchicalKMeans(s.pts);
	const auto b = cluster::hierarchicalKMeans(s.pts);
	EXPECT_EQ(a.cluster, b.cluster);
	EXPECT_EQ(a.sizes, b.sizes);
}

TEST(HierarchicalKMeans, SameClustersOnAnyThreadCount)
{
	// 9000 points: above the size from which the root's groups are split
	// on several threads.
	const auto s = makeStems(3, 15, 600);
	cluster::ClusterOptions one;
	one.threads = 1;
	const auto a = cluster::hierarchicalKMeans(s.pts, one);
	for (int threads : {2, 3, 8})
	{
		cluster::ClusterOptions o;
		o.threads = threads;
		const auto b = cluster::hierarchicalKMeans(s.pts, o);
		EXPECT_EQ(a.cluster, b.cluster) << threads << " threads";
		EXPECT_EQ(a.sizes, b.sizes) << threads << " threads";
		ASSERT_EQ(a.centroids.size(), b.centroids.size());
		for (size_t c = 0; c < a.centroids.size(); c++)
			EXPECT_EQ(a.centroids[c], b.centroids[c]) << c;
	}
	EXPECT_GT(a.clusterCount(), 9000u / one.max_cluster_points);
}

TEST(HierarchicalKMeans, SmallClustersMergeIntoNearNeighboursOnly)
{
	// 300 points of a blob + 3 points 0.3 m away (merge) + 3 points 20 m
	// away (stay alone, beyond max_merge_distance_m).
	std::vector<Eigen::Vector3f> pts;
	std::mt19937 rng(3);
	std::normal_distribution<float> N(0, 0.1f);
	for (int i = 0; i < 300; i++) pts.emplace_back(N(rng), N(rng), N(rng));
	for (int i = 0; i < 3; i++) pts.emplace_back(0.35f + 0.01f * i, 0, 0);
	for (int i = 0; i < 3; i++) pts.emplace_back(20.f + 0.01f * i, 0, 0);
	pts.emplace_back(NAN, 0, 0);
	cluster::ClusterOptions o;
	o.max_cluster_points = 100;
	o.min_cluster_points = 10;
	const auto L = cluster::hierarchicalKMeans(pts, o);
	EXPECT_EQ(L.cluster.back(), -1);
	const int far = L.cluster[303];
	for (int i = 304; i < 306; i++) EXPECT_EQ(L.cluster[i], far);
	EXPECT_EQ(L.sizes[far], 3u);
	for (int i = 300; i < 303; i++) EXPECT_NE(L.sizes[L.cluster[i]], 3u);
}

TEST(HierarchicalKMeans, EdgeCases)
{
	EXPECT_EQ(cluster::hierarchicalKMeans({}).clusterCount(), 0u);
	std::vector<Eigen::Vector3f> same(500, Eigen::Vector3f(1, 2, 3));
	const auto L = cluster::hierarchicalKMeans(same);
	EXPECT_EQ(L.clusterCount(), 1u);
	EXPECT_EQ(L.sizes[0], 500u);
	auto cfg = core::TrackedConfig::fromText("[cluster]\nbranching_factor = 1\n", "c.ini");
	cluster::ClusterOptions o;
	EXPECT_THROW(o.loadFromConfigFile(cfg, "cluster"), core::ConfigError);
}
