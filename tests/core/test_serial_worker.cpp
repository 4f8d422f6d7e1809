#include <forest_slam/core/memory.h>
#include <forest_slam/core/serial_worker.h>
#include <gtest/gtest.h>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <future>
#include <stdexcept>
#include <thread>
#include <vector>

using forest_slam::core::SerialWorker;

TEST(SerialWorker, RunsJobsInPushOrderOffTheCallersThread)
{
	std::vector<int> order;
	std::vector<std::thread::id> ran_on;
	SerialWorker w(2);
	EXPECT_TRUE(w.threaded());
	for (int i = 0; i < 50; i++)
		w.push(
		    [&, i]
		    {
			    // Early jobs are slow: a later one must still wait its turn.
			    if (i < 3)
				    std::this_thread::sleep_for(std::chrono::milliseconds(5));
			    order.push_back(i);
			    ran_on.push_back(std::this_thread::get_id());
		    });
	w.flush();
	ASSERT_EQ(order.size(), 50u);
	for (int i = 0; i < 50; i++) EXPECT_EQ(order[i], i);
	for (const auto& id : ran_on) EXPECT_NE(id, std::this_thread::get_id());
}

TEST(SerialWorker, ZeroPendingRunsInline)
{
	SerialWorker w(0);
	EXPECT_FALSE(w.threaded());
	std::thread::id ran_on;
	int value = 0;
	w.push(
	    [&]
	    {
		    ran_on = std::this_thread::get_id();
		    value = 7;
	    });
	EXPECT_EQ(value, 7);  // done before push() returned
	EXPECT_EQ(ran_on, std::this_thread::get_id());
}

TEST(SerialWorker, BoundsTheQueue)
{
	// With one job pending at most, push() blocks until the worker takes
	// the previous one: never more than 2 jobs (1 queued + 1 running) are
	// pushed and unfinished.
	SerialWorker w(1);
	std::atomic<int> started{0}, finished{0};
	int max_unfinished = 0;
	for (int i = 0; i < 20; i++)
	{
		w.push(
		    [&]
		    {
			    started++;
			    std::this_thread::sleep_for(std::chrono::milliseconds(1));
			    finished++;
		    });
		max_unfinished = std::max(max_unfinished, i + 1 - finished.load());
	}
	w.flush();
	EXPECT_EQ(finished.load(), 20);
	EXPECT_LE(max_unfinished, 2);
}

TEST(SerialWorker, RethrowsAJobErrorOnceAndDropsTheJobsAfterIt)
{
	SerialWorker w(4);
	int ran_after = 0;
	// The failing job waits until the next one is queued: a push() after
	// the failure would rethrow it there instead (ThreadSanitizer's timing
	// found this race in the test).
	std::promise<void> queued;
	std::shared_future<void> next_is_queued = queued.get_future().share();
	w.push(
	    [next_is_queued]
	    {
		    next_is_queued.wait();
		    throw std::runtime_error("disk full");
	    });
	w.push([&] { ran_after++; });
	queued.set_value();
	try
	{
		w.flush();
		FAIL() << "flush() should rethrow the job's error";
	}
	catch (const std::runtime_error& e)
	{
		EXPECT_STREQ(e.what(), "disk full");
	}
	EXPECT_EQ(ran_after, 0);
	// Reported once: the worker goes on with new jobs.
	w.push([&] { ran_after++; });
	w.flush();
	EXPECT_EQ(ran_after, 1);
}

TEST(SerialWorker, DestructorRunsTheQueuedJobs)
{
	std::atomic<int> done{0};
	{
		SerialWorker w(8);
		for (int i = 0; i < 8; i++)
			w.push(
			    [&]
			    {
				    std::this_thread::sleep_for(std::chrono::milliseconds(1));
				    done++;
			    });
	}
	EXPECT_EQ(done.load(), 8);
}

TEST(SerialWorker, NamedThreadReportsItsCpu)
{
	using forest_slam::core::threadCpuByName;
	using forest_slam::core::threadCpuSeconds;
	SerialWorker w(2, "fs-test-spin");
	// Spins until this worker thread itself has used 0.15 s of CPU, however
	// loaded the machine is.
	w.push(
	    []
	    {
		    const double c0 = threadCpuSeconds();
		    volatile double x = 0;
		    while (threadCpuSeconds() - c0 < 0.15) x = x + 1;
	    });
	w.flush();
	const auto threads = threadCpuByName();
	ASSERT_FALSE(threads.empty());
	double spin_s = -1;
	for (const auto& [name, s] : threads)
		if (name == "fs-test-spin") spin_s = s;
	// /proc counts in clock ticks (10 ms): 0.15 s shows as 0.14-0.17 s.
	EXPECT_GE(spin_s, 0.12);
	EXPECT_LT(spin_s, 1.0);
}

TEST(SerialWorker, BackgroundWorkerRunsAtALowerPriority)
{
	// The nice value of the worker's own thread, read on that thread: the
	// lowest priority for a background worker, its creator's otherwise.
	auto niceOfWorker = [](bool background)
	{
		SerialWorker w(2, "fs-test-nice", background);
		int nice = 0;
		w.push(
		    [&]
		    {
			    errno = 0;
			    nice = getpriority(PRIO_PROCESS,
			                       static_cast<id_t>(syscall(SYS_gettid)));
			    ASSERT_EQ(errno, 0);
		    });
		w.flush();
		return nice;
	};
	errno = 0;
	const int mine =
	    getpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)));
	ASSERT_EQ(errno, 0);
	EXPECT_EQ(niceOfWorker(false), mine);
	namespace core = forest_slam::core;
	ASSERT_EQ(core::backgroundNice(), core::kBackgroundNiceRecorded);
	EXPECT_EQ(niceOfWorker(true),
	          std::min(19, mine + core::kBackgroundNiceRecorded));
	// Live input: a step below the creator only.
	core::setBackgroundNice(core::kBackgroundNiceLive);
	EXPECT_EQ(niceOfWorker(true),
	          std::min(19, mine + core::kBackgroundNiceLive));
	core::setBackgroundNice(core::kBackgroundNiceRecorded);
	// The caller's own priority is left alone.
	EXPECT_EQ(getpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid))),
	          mine);
}
