// core/memory: the heap kept for reuse during a phase that allocates and
// frees the same big buffers (the end-of-run tree detection).
#include <forest_slam/core/memory.h>
#include <gtest/gtest.h>

#include <sys/resource.h>

#include <cstdlib>
#include <cstring>

using namespace forest_slam::core;

namespace
{
long minorFaults()
{
	rusage u{};
	getrusage(RUSAGE_SELF, &u);
	return u.ru_minflt;
}

/** Minor page faults of allocating, touching and freeing `bytes` twice:
 * those of the second time only. */
long faultsOfASecondBuffer(size_t bytes)
{
	for (int i = 0; i < 2; i++)
	{
		const long before = minorFaults();
		char* p = static_cast<char*>(std::malloc(bytes));
		EXPECT_NE(p, nullptr);
		std::memset(p, 1, bytes);
		// Keep the writes (the buffer is freed right away otherwise).
		volatile char sink = p[bytes / 2];
		(void)sink;
		std::free(p);
		if (i == 1) return minorFaults() - before;
	}
	return 0;
}
}  // namespace

TEST(Memory, HeapKeptForReuseReusesAFreedBigBuffer)
{
	returnBigBlocksToTheSystem();
	const size_t bytes = 16 << 20;  // above the 4 MB threshold
	// Each buffer its own mapping: the second is mapped and faulted afresh
	// (4096 faults of 4 kB pages; a few with transparent huge pages).
	const long returned = faultsOfASecondBuffer(bytes);
	long kept = 0;
	{
		const HeapKeptForReuse keep;
		kept = faultsOfASecondBuffer(bytes);
	}
	EXPECT_LE(kept, 8) << "the second buffer was faulted in afresh";
	EXPECT_GT(returned, kept);
	// Back to the process's setting: mapped (and faulted) afresh again.
	EXPECT_GT(faultsOfASecondBuffer(bytes), kept);
}
