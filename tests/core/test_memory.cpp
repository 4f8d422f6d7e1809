// Memory accounting: the resident set and malloc's own view of the heap
// follow what the program allocates and frees.
#include <forest_slam/core/memory.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>
#include <vector>

using namespace forest_slam;

namespace
{
/** Keeps the compiler from dropping an allocation it sees is unused. */
void escape(void* p)
{
	asm volatile("" : : "g"(p) : "memory");
}
}  // namespace

TEST(Memory, HeapUseCountsBlocksHandedOutAndFreed)
{
	const core::HeapUse before = core::heapUse();
	EXPECT_GE(before.arenas, 1);
	// Many small blocks (from the heap, not mapped apart): 64 MB.
	std::vector<std::unique_ptr<char[]>> blocks;
	for (int i = 0; i < 64 * 1024; i++)
	{
		blocks.emplace_back(new char[1000]);
		escape(blocks.back().get());
	}
	const core::HeapUse held = core::heapUse();
	EXPECT_GE(held.in_use_mb - before.in_use_mb, 60.0);
	// Every other block freed: the holes stay in the heap as free memory.
	for (size_t i = 0; i < blocks.size(); i += 2) blocks[i].reset();
	const core::HeapUse holes = core::heapUse();
	EXPECT_LE(holes.in_use_mb - before.in_use_mb, 40.0);
	EXPECT_GE(holes.free_mb - before.free_mb, 25.0);
}

TEST(Memory, LargeBlockIsMappedApartAndCountedInUse)
{
	const core::HeapUse before = core::heapUse();
	// 256 MB is above any mmap threshold glibc sets by itself.
	std::unique_ptr<char[]> big(new char[256 << 20]);
	escape(big.get());
	const core::HeapUse after = core::heapUse();
	EXPECT_GE(after.mapped_mb - before.mapped_mb, 255.0);
	EXPECT_GE(after.in_use_mb - before.in_use_mb, 255.0);
}

TEST(Memory, ResidentSetFollowsTouchedPages)
{
	const double rss0 = core::currentRssMb();
	ASSERT_GT(rss0, 0.0);
	std::vector<char> touched(128 << 20, 1);
	EXPECT_GE(core::currentRssMb() - rss0, 100.0);
	EXPECT_GE(core::peakRssMb(), core::currentRssMb() - 1.0);
	EXPECT_EQ(touched[12345], 1);
}
