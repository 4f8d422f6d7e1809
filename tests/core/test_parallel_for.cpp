#include <forest_slam/core/parallel_for.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

using forest_slam::core::parallelFor;
using forest_slam::core::parallelRanges;

TEST(ParallelFor, EveryIndexOnceForAnyThreadCountAndChunk)
{
	for (int threads : {1, 2, 3, 8})
		for (size_t chunk : {1, 7, 32, 1000})
			for (size_t n : {0, 1, 31, 32, 33, 1000})
			{
				std::vector<std::atomic<int>> hits(n);
				parallelFor(n, threads, chunk, [&](size_t i) { hits[i]++; });
				for (size_t i = 0; i < n; i++)
					ASSERT_EQ(hits[i].load(), 1)
					    << "i " << i << " threads " << threads << " chunk "
					    << chunk << " n " << n;
			}
}

TEST(ParallelFor, HelpersTakeChunksAndWorkerIndicesStayInRange)
{
	// Slow chunks: the caller cannot take them all before a helper wakes.
	std::set<int> workers;
	std::mutex m;
	std::atomic<size_t> total{0};
	for (int rep = 0; rep < 20; rep++)
		parallelRanges(
		    64, 2, 1,
		    [&](size_t b, size_t e, int w)
		    {
			    std::this_thread::sleep_for(std::chrono::microseconds(200));
			    total += e - b;
			    const std::lock_guard<std::mutex> g(m);
			    workers.insert(w);
		    });
	EXPECT_EQ(total.load(), 20u * 64u);
	EXPECT_EQ(workers, (std::set<int>{0, 1}));
}

TEST(ParallelFor, ExceptionReachesTheCallerAndThePoolStillWorks)
{
	for (int thrower : {0, 63})  // early (caller's chunk) and late
	{
		EXPECT_THROW(parallelFor(64, 2, 1,
		                         [&](size_t i)
		                         {
			                         std::this_thread::sleep_for(
			                             std::chrono::microseconds(50));
			                         if (int(i) == thrower)
				                         throw std::runtime_error("bad item");
		                         }),
		             std::runtime_error);
		std::atomic<size_t> sum{0};
		parallelFor(100, 2, 3, [&](size_t i) { sum += i; });
		EXPECT_EQ(sum.load(), 4950u);
	}
}

TEST(ParallelFor, EachCallingThreadHasItsOwnHelpers)
{
	// Two threads running loops at once do not share (or deadlock on) one
	// pool.
	auto job = [](size_t& out)
	{
		for (int rep = 0; rep < 200; rep++)
		{
			std::atomic<size_t> s{0};
			parallelFor(1000, 2, 16, [&](size_t i) { s += i; });
			out += s.load();
		}
	};
	size_t a = 0, b = 0;
	std::thread t1(job, std::ref(a)), t2(job, std::ref(b));
	t1.join();
	t2.join();
	EXPECT_EQ(a, 200u * 499500u);
	EXPECT_EQ(b, 200u * 499500u);
}
