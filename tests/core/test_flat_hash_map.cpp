// FlatHashMap: the open-addressing table behind the voxel map and the
// odometry's local map, checked against std::map on random operations.
#include <forest_slam/core/flat_hash_map.h>
#include <gtest/gtest.h>

#include <map>
#include <random>

using forest_slam::core::FlatHashMap;
using forest_slam::core::packCellKey;
using forest_slam::core::unpackCellIndex;

TEST(FlatHashMap, PackedKeysRoundTripSignedIndices)
{
	for (int64_t i : {-1048575LL, -1000LL, -1LL, 0LL, 1LL, 77LL, 1048575LL})
		for (int64_t j : {-5LL, 0LL, 3LL})
			for (int64_t k : {-1048575LL, -2LL, 9LL})
			{
				const uint64_t key = packCellKey(i, j, k);
				EXPECT_EQ(key >> 63, 0u);  // the empty marker stays free
				EXPECT_EQ(unpackCellIndex(key, 0), i);
				EXPECT_EQ(unpackCellIndex(key, 1), j);
				EXPECT_EQ(unpackCellIndex(key, 2), k);
			}
	EXPECT_NE(packCellKey(-1, 0, 0), packCellKey(0, -1, 0));
	EXPECT_NE(packCellKey(0, 0, -1), packCellKey(0, 0, 1));
}

TEST(FlatHashMap, AgreesWithStdMapOnRandomInsertsFindsAndErases)
{
	FlatHashMap<int> flat;
	std::map<uint64_t, int> ref;
	std::mt19937 rng(7);
	// Neighbouring cells: the keys linear probing finds hardest.
	std::uniform_int_distribution<int> c(-40, 40);
	for (int round = 0; round < 5; round++)
	{
		for (int n = 0; n < 20000; n++)
		{
			const uint64_t k = packCellKey(c(rng), c(rng), c(rng) / 8);
			bool added = false;
			flat.tryEmplace(k, &added) += n;
			EXPECT_EQ(added, ref.count(k) == 0);
			ref[k] += n;
		}
		ASSERT_EQ(flat.size(), ref.size());
		for (const auto& [k, v] : ref)
		{
			const int* f = flat.find(k);
			ASSERT_NE(f, nullptr);
			EXPECT_EQ(*f, v);
		}
		EXPECT_EQ(flat.find(packCellKey(1000, 1000, 1000)), nullptr);
		// Erase about half (odd values), as LocalMap::prune does by distance.
		flat.eraseIf([](uint64_t, int v) { return v % 2 != 0; });
		for (auto it = ref.begin(); it != ref.end();)
			it = it->second % 2 != 0 ? ref.erase(it) : std::next(it);
		ASSERT_EQ(flat.size(), ref.size());
		size_t seen = 0;
		flat.forEach(
		    [&](uint64_t k, int v)
		    {
			    seen++;
			    ASSERT_TRUE(ref.count(k));
			    EXPECT_EQ(ref.at(k), v);
		    });
		EXPECT_EQ(seen, ref.size());
	}
	flat.clear();
	EXPECT_TRUE(flat.empty());
	EXPECT_EQ(flat.find(packCellKey(0, 0, 0)), nullptr);
}

TEST(FlatHashMap, ReserveKeepsValuePointersValidWhileAdding)
{
	FlatHashMap<double> flat;
	flat[packCellKey(-9, -9, -9)] = 1;
	flat.reserve(5000);
	const size_t bytes = flat.memoryBytes();
	double& first = flat[packCellKey(1, 2, 3)];
	first = 4.5;
	for (int i = 0; i < 4998; i++) flat[packCellKey(i, -i, 7)] = i;
	ASSERT_EQ(flat.size(), 5000u);
	EXPECT_EQ(&first, flat.find(packCellKey(1, 2, 3)));  // did not move
	EXPECT_EQ(flat.memoryBytes(), bytes);                // did not grow
	for (int i = 0; i < 5000; i++) flat[packCellKey(i, i, -7)] = i;
	EXPECT_GT(flat.memoryBytes(), bytes);  // grew, values moved with it
	EXPECT_EQ(*flat.find(packCellKey(1, 2, 3)), 4.5);
	EXPECT_EQ(*flat.find(packCellKey(-9, -9, -9)), 1.0);
	EXPECT_EQ(flat.size(), 10000u);
}
