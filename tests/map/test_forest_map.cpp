#include <forest_slam/core/config.h>
#include <forest_slam/io/rawlog_reader.h>
#include <forest_slam/map/forest_map.h>
#include <gtest/gtest.h>
#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/maps/CMultiMetricMap.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/serialization/CArchive.h>

#include <filesystem>

using namespace forest_slam;
using map::CForestMap;

TEST(VoxelCloud, KeepsExactCentroidPerVoxel)
{
	map::VoxelCloud c(0.5f);
	c.insert({0.1f, 0.1f, 0.1f});
	c.insert({0.3f, 0.1f, 0.1f});
	c.insert({0.7f, 0.1f, 0.1f});  // next voxel in x
	c.insert({NAN, 0, 0});         // ignored
	ASSERT_EQ(c.size(), 2u);
	Eigen::Vector3f cen;
	ASSERT_TRUE(c.centroidAt({0.2f, 0.2f, 0.2f}, cen));
	EXPECT_TRUE(cen.isApprox(Eigen::Vector3f(0.2f, 0.1f, 0.1f)));
	float d2;
	ASSERT_TRUE(c.nearestAround({0.9f, 0.1f, 0.1f}, cen, d2));
	EXPECT_NEAR(cen.x(), 0.7f, 1e-6);
	EXPECT_THROW(c.setVoxelSize(0), std::invalid_argument);
}

TEST(ForestMap, InsertionVoxelFilteringAndSubmaps)
{
	map::ForestMapOptions o;
	o.submap_size_m = 20;
	o.edge_voxel_m = 0.1;
	o.planar_voxel_m = 0.5;
	CForestMap m(o);
	EXPECT_TRUE(m.isEmpty());
	// A 10 x 10 m ground patch sampled every 5 cm -> (10/0.5)^2 planar voxels,
	// a vertical line (stem) sampled every 1 cm over 2 m -> 20 edge voxels.
	std::vector<Eigen::Vector3f> planar, edge;
	for (int i = 0; i < 200; i++)
		for (int j = 0; j < 200; j++)
			planar.emplace_back(0.025f + i * 0.05f, 0.025f + j * 0.05f, 0.01f);
	for (int k = 0; k < 200; k++)
		edge.emplace_back(5.05f, 5.05f, 0.005f + k * 0.01f);
	m.insertFeatures(edge, planar);
	EXPECT_EQ(m.planarPointCount(), 400u);
	EXPECT_EQ(m.edgePointCount(), 20u);
	EXPECT_EQ(m.submaps().size(), 1u);
	// Re-inserting the same points does not grow the map.
	m.insertFeatures(edge, planar);
	EXPECT_EQ(m.planarPointCount(), 400u);
	// Points 30 m away land in another submap.
	m.insertFeatures({}, {Eigen::Vector3f(35, 5, 0)});
	EXPECT_EQ(m.submaps().size(), 2u);
	EXPECT_EQ(m.getAsSimplePointsMap()->size(), 421u);
	const auto bb = m.boundingBox();
	EXPECT_NEAR(bb.max.x, 35, 1e-3);
	EXPECT_FALSE(m.isEmpty());
	m.clear();
	EXPECT_TRUE(m.isEmpty());
}

TEST(ForestMap, BulkInsertionMatchesPointByPointInsertion)
{
	// insertFeatures computes the keys first and prefetches slots ahead:
	// every voxel must end with the count and centroid that inserting the
	// points one by one into a VoxelCloud gives, also across a submap
	// border, over two scans, and with a sensor pose.
	map::ForestMapOptions o;
	o.submap_size_m = 20;
	o.edge_voxel_m = 0.1;
	o.planar_voxel_m = 0.2;
	CForestMap m(o);
	map::VoxelCloud edge_oracle(0.1f), planar_oracle(0.2f);
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	T.translate(Eigen::Vector3d(15.3, -2.1, 0.4));
	T.rotate(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()));
	uint32_t state = 7;
	auto uniform = [&state](float lo, float hi)
	{
		state = state * 1664525u + 1013904223u;
		return lo + (hi - lo) * static_cast<float>(state >> 8) / 16777216.f;
	};
	size_t planar_points = 0;
	for (int scan = 0; scan < 2; scan++)
	{
		std::vector<Eigen::Vector3f> edge, planar;
		for (int i = 0; i < 3000; i++)  // ground across submap borders
			planar.emplace_back(uniform(0, 9), uniform(-3, 3),
			                    uniform(-0.6f, -0.5f));
		for (int i = 0; i < 500; i++)  // a stem, many points per voxel
			edge.emplace_back(uniform(3, 3.25f), uniform(1, 1.25f),
			                  uniform(0, 2));
		edge.emplace_back(NAN, 0, 0);  // dropped
		m.insertFeatures(edge, planar, T);
		const Eigen::Isometry3f Tf = T.cast<float>();
		for (const auto& p : edge)
			if (p.allFinite()) edge_oracle.insert(Tf * p);
		for (const auto& p : planar) planar_oracle.insert(Tf * p);
		planar_points += planar.size();
	}
	size_t planar_voxels = 0, edge_voxels = 0, counted = 0;
	size_t submaps_with_planar = 0;
	for (const auto& [key, sm] : m.submaps())
	{
		if (!sm.planar.empty()) submaps_with_planar++;
		auto check = [&](const map::VoxelCloud& oracle, const map::VoxelKey& k,
		                 const map::VoxelCloud::Accum& a, size_t& voxels)
		{
			const Eigen::Vector3f c = a.centroid();
			Eigen::Vector3f oc;
			ASSERT_TRUE(oracle.centroidAt(c, oc));
			EXPECT_LT((c - oc).norm(), 1e-4f)
			    << k.x << " " << k.y << " " << k.z;
			voxels++;
			counted += a.count;
		};
		sm.planar.forEachVoxel([&](const map::VoxelKey& k, const auto& a)
		                       { check(planar_oracle, k, a, planar_voxels); });
		sm.edge.forEachVoxel([&](const map::VoxelKey& k, const auto& a)
		                     { check(edge_oracle, k, a, edge_voxels); });
	}
	EXPECT_EQ(planar_voxels, planar_oracle.size());
	EXPECT_EQ(edge_voxels, edge_oracle.size());
	EXPECT_EQ(counted, planar_points + 1000u);
	EXPECT_EQ(submaps_with_planar, 4u);  // ground across x = 20, y = 0
	EXPECT_LT(edge_voxels, 200u);        // 500 points a scan, few voxels
}

TEST(ForestMap, NeighbourhoodQuery)
{
	CForestMap m;  // 20 m submaps
	std::vector<Eigen::Vector3f> pts;
	for (int x = -50; x <= 50; x += 10)
		for (int y = -50; y <= 50; y += 10)
			pts.emplace_back(x + 0.5f, y + 0.5f, 1.f);
	m.insertFeatures({}, pts);
	std::vector<Eigen::Vector3f> e, p;
	m.collectNear({0, 0, 0}, 5.0, e, p);
	// A 5 m sphere at the origin touches the 4 occupied submaps covering
	// [-20,20)^2 (z in [0,20)); they hold x,y in {-19.5,-9.5,0.5,10.5}.
	const auto keys = m.submapsNear({0, 0, 0}, 5.0);
	EXPECT_EQ(keys.size(), 4u);
	EXPECT_EQ(p.size(), 16u);
	for (const auto& q : p) EXPECT_LT(q.head<2>().cwiseAbs().maxCoeff(), 20.f);
	m.collectNear({0, 0, 0}, 60.0, e, p);
	EXPECT_EQ(p.size(), pts.size());
	m.collectNear({500, 0, 0}, 10.0, e, p);
	EXPECT_TRUE(p.empty());
}

TEST(ForestMap, SerializationRoundTrip)
{
	map::ForestMapOptions o;
	o.edge_voxel_m = 0.15;
	CForestMap m(o);
	m.insertFeatures({{1, 2, 3}, {1.01f, 2, 3}}, {{-30, 4, 0}, {5, 5, 5}});
	map::TreeRecord t;
	t.id = 7;
	t.x = 1.5;
	t.dbh_m = 0.31;
	t.n_points = 250;
	m.setTrees({t});

	mrpt::io::CMemoryStream buf;
	auto out = mrpt::serialization::archiveFrom(buf);
	out << m;
	buf.Seek(0);
	auto in = mrpt::serialization::archiveFrom(buf);
	auto obj = in.ReadObject();
	auto back = std::dynamic_pointer_cast<CForestMap>(obj);
	ASSERT_TRUE(back);
	EXPECT_DOUBLE_EQ(back->options().edge_voxel_m, 0.15);
	EXPECT_EQ(back->edgePointCount(), m.edgePointCount());
	EXPECT_EQ(back->planarPointCount(), 2u);
	EXPECT_EQ(back->submaps().size(), m.submaps().size());
	ASSERT_EQ(back->trees().size(), 1u);
	EXPECT_EQ(back->trees()[0].id, 7u);
	EXPECT_DOUBLE_EQ(back->trees()[0].dbh_m, 0.31);
	EXPECT_EQ(back->trees()[0].n_points, 250u);
	std::vector<Eigen::Vector3f> e1, p1, e2, p2;
	m.collectNear({0, 0, 0}, 100, e1, p1);
	back->collectNear({0, 0, 0}, 100, e2, p2);
	ASSERT_EQ(e1.size(), e2.size());
	EXPECT_TRUE(e1[0].isApprox(e2[0]));
}

TEST(ForestMap, CreatedByMultiMetricMapFromIni)
{
	map::registerForestMapClasses();
	const std::string ini = R"(
[map]
forestMap_count = 1
[map_forestMap_00_creationOpts]
submap_size_m = 10
edge_voxel_m = 0.05
planar_voxel_m = 0.25
)";
	auto cfg = core::TrackedConfig::fromText(ini, "mmm.ini");
	mrpt::maps::TSetOfMetricMapInitializers inits;
	inits.loadFromConfigFile(cfg, "map");
	ASSERT_EQ(inits.size(), 1u);
	mrpt::maps::CMultiMetricMap mm(inits);
	ASSERT_EQ(mm.maps.size(), 1u);
	auto fm = std::dynamic_pointer_cast<CForestMap>(mm.maps[0]);
	ASSERT_TRUE(fm);
	EXPECT_DOUBLE_EQ(fm->options().submap_size_m, 10);
	EXPECT_DOUBLE_EQ(fm->options().edge_voxel_m, 0.05);
	EXPECT_DOUBLE_EQ(fm->options().planar_voxel_m, 0.25);
	// Every key of the INI was consumed by MRPT's loader + our options.
	EXPECT_NO_THROW(cfg.checkNoUnknownKeys());

	auto bad = core::TrackedConfig::fromText(
	    "[map]\nforestMap_count = "
	    "1\n[map_forestMap_00_creationOpts]\nedge_voxel_m = -1\n",
	    "bad.ini");
	mrpt::maps::TSetOfMetricMapInitializers inits2;
	EXPECT_THROW(inits2.loadFromConfigFile(bad, "map"), std::exception);
}

TEST(ForestMap, InsertsRealScanAndLikelihoodPeaksAtTruePose)
{
	io::RawlogReader r(std::string(FOREST_SLAM_SHARED_DIR) +
	                   "/data/mrpt/rot_scan_velodyne.rawlog");
	auto obs = r.next();
	auto scan =
	    std::dynamic_pointer_cast<mrpt::obs::CObservationRotatingScan>(obs);
	ASSERT_TRUE(scan);
	scan->lidarModel = "VLP16";
	CForestMap m;
	ASSERT_TRUE(m.insertObservation(*scan, mrpt::poses::CPose3D()));
	EXPECT_GT(m.edgePointCount(), 50u);
	EXPECT_GT(m.planarPointCount(), 500u);
	EXPECT_TRUE(m.canComputeObservationLikelihood(*scan));
	const double at_true =
	    m.computeObservationLikelihood(*scan, mrpt::poses::CPose3D());
	const double shifted = m.computeObservationLikelihood(
	    *scan, mrpt::poses::CPose3D(0.6, 0.3, 0, 0.1, 0, 0));
	EXPECT_GT(at_true, shifted + 10.0);

	const auto prefix = (std::filesystem::temp_directory_path() /
	                     ("fs_map_" + std::to_string(::getpid())))
	                        .string();
	m.saveMetricMapRepresentationToFile(prefix);
	EXPECT_GT(std::filesystem::file_size(prefix + "_edge.xyz"), 100u);
	EXPECT_GT(std::filesystem::file_size(prefix + "_planar.xyz"), 1000u);
	EXPECT_TRUE(std::filesystem::exists(prefix + "_trees.csv"));
}

TEST(ForestMap, SegmentsFollowTheirOwnCorrection)
{
	// A stem mapped twice: first by a drifted pass 0.6 m east of where it
	// stands, then (after the back-end's correction) where it stands. Kept
	// apart as two segments, each moves with its own correction: the
	// drifted one back by 0.6 m, the other not at all; once merged the
	// stem is one column of voxels holding both passes' points.
	map::ForestMapOptions o;
	o.edge_voxel_m = 0.1;
	o.planar_voxel_m = 0.5;
	CForestMap m(o);
	auto stem = [](float x)
	{
		std::vector<Eigen::Vector3f> e;
		for (int k = 0; k < 200; k++)
			e.emplace_back(x + 0.03f, 5.05f, 0.005f + k * 0.01f);
		return e;
	};
	m.insertFeatures(stem(10.6f), {Eigen::Vector3f(10.6f, 5, -1)});
	EXPECT_EQ(m.segmentCount(), 1u);
	m.startSegment();
	EXPECT_EQ(m.segmentCount(), 2u);
	m.insertFeatures(stem(10.0f), {Eigen::Vector3f(10.0f, 5, -1)});
	// Both segments counted while apart; a voxel of the same place in
	// another segment is another voxel.
	EXPECT_EQ(m.edgePointCount(), 40u);
	EXPECT_EQ(m.planarPointCount(), 2u);
	EXPECT_EQ(m.submaps().size(), 2u);  // the current segment's (z < 0, z > 0)
	EXPECT_GT(m.memoryBytes(), 0u);
	// Serializing a map with segments apart is a programming error
	// (MRPT rethrows it wrapped).
	{
		mrpt::io::CMemoryStream buf;
		auto arch = mrpt::serialization::archiveFrom(buf);
		EXPECT_ANY_THROW(arch << m);
	}
	std::vector<size_t> asked(2, 0);
	m.transformSegments(
	    [&](size_t s, const Eigen::Vector3f& c)
	    {
		    EXPECT_LT(s, 2u);
		    asked.at(s)++;
		    Eigen::Isometry3f T = Eigen::Isometry3f::Identity();
		    if (s == 0) T.translation() = Eigen::Vector3f(-0.6f, 0, 0);
		    EXPECT_TRUE(c.allFinite());
		    return T;
	    });
	EXPECT_EQ(asked[0], 21u);
	EXPECT_EQ(asked[1], 21u);
	EXPECT_EQ(m.segmentCount(), 1u);
	EXPECT_EQ(m.edgePointCount(), 20u);
	EXPECT_EQ(m.planarPointCount(), 1u);
	size_t n = 0;
	for (const auto& kv : m.submaps())
		kv.second.edge.forEachVoxel(
		    [&](const map::VoxelKey&, const map::VoxelCloud::Accum& a)
		    {
			    EXPECT_EQ(a.count, 20u);  // 10 points of each pass
			    EXPECT_NEAR(a.centroid().x(), 10.03f, 1e-4);
			    n++;
		    });
	EXPECT_EQ(n, 20u);
	// The merged map serializes again.
	mrpt::io::CMemoryStream buf;
	auto arch = mrpt::serialization::archiveFrom(buf);
	EXPECT_NO_THROW(arch << m);
}

TEST(ForestMap, FrozenSegmentIsCompactAndMergesBackUnchanged)
{
	// 30 x 30 x 4 edge voxels and a ground of planar voxels over three
	// submaps, mapped once into a map that is never split and once into one
	// whose segment is frozen and then merged back with no correction.
	map::ForestMapOptions o;
	o.submap_size_m = 20;
	o.edge_voxel_m = 0.2;
	o.planar_voxel_m = 0.4;
	std::vector<Eigen::Vector3f> edge, planar;
	for (int i = 0; i < 30; i++)
		for (int j = 0; j < 30; j++)
		{
			for (int k = 0; k < 4; k++)
				edge.emplace_back(15 + 0.2f * i + 0.05f, 0.2f * j + 0.07f,
				                  0.2f * k + 0.11f);
			planar.emplace_back(0.4f * i + 0.1f, 1.3f * j + 0.2f, -0.3f);
		}
	CForestMap whole(o), split(o);
	whole.insertFeatures(edge, planar);
	split.insertFeatures(edge, planar);
	const size_t table_bytes = split.memoryBytes();
	split.startSegment();
	EXPECT_EQ(split.segmentCount(), 2u);
	EXPECT_TRUE(split.submaps().empty());
	EXPECT_EQ(split.edgePointCount(), 3600u);
	EXPECT_EQ(split.planarPointCount(), 900u);
	// Sum and count only: 16 bytes a voxel (plus a few per submap), where
	// the tables hold ~50.
	EXPECT_LE(split.memoryBytes(), 4500u * 16 + 256);
	EXPECT_GT(table_bytes, 2 * split.memoryBytes());
	split.transformSegments([](size_t, const Eigen::Vector3f&)
	                        { return Eigen::Isometry3f::Identity(); });
	EXPECT_EQ(split.segmentCount(), 1u);
	ASSERT_EQ(split.submaps().size(), whole.submaps().size());
	for (const auto& [key, sm] : whole.submaps())
	{
		const auto it = split.submaps().find(key);
		ASSERT_NE(it, split.submaps().end());
		for (const bool edges : {true, false})
		{
			const auto& a = edges ? sm.edge : sm.planar;
			const auto& b = edges ? it->second.edge : it->second.planar;
			ASSERT_EQ(a.size(), b.size());
			a.forEachVoxel(
			    [&](const map::VoxelKey&, const map::VoxelCloud::Accum& v)
			    {
				    Eigen::Vector3f c;
				    ASSERT_TRUE(b.centroidAt(v.centroid(), c));
				    EXPECT_NEAR((c - v.centroid()).norm(), 0, 1e-5);
			    });
		}
	}
}
