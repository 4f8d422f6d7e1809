#pragma once
// Runs jobs on one worker thread, in the order they were pushed, while the
// caller goes on with other work: the odometry's map insertions and the
// output collection overlap the next scan's front-end and registration.
// The caller decides when it needs a job's result and calls flush() first;
// with jobs run in push order the results are the same as running them
// inline (bit-identical runs, whatever the thread timing).
#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>

namespace forest_slam::core
{
class SerialWorker
{
   public:
	/** max_pending: jobs waiting at most (push() blocks beyond it, so the
	 * memory they hold stays bounded when the worker falls behind). 0 runs
	 * every job inline in push() (no thread). name: the thread's name (at
	 * most 15 characters), so that top -H and perf tell the workers apart.
	 * background: the thread runs at a lower priority (nice +5), for work
	 * nobody waits for while the queue has room (see
	 * core::runInBackground). */
	explicit SerialWorker(size_t max_pending, const char* name = "fs-worker",
	                      bool background = false);
	/** Runs the jobs still queued, then joins. */
	~SerialWorker();
	SerialWorker(const SerialWorker&) = delete;
	SerialWorker& operator=(const SerialWorker&) = delete;

	/** Queues a job. An exception thrown by an earlier job is rethrown here
	 * (once), and jobs queued after the failed one are dropped. */
	void push(std::function<void()> job);
	/** Returns when every queued job has run; rethrows a job's exception. */
	void flush();
	bool threaded() const { return max_pending_ > 0; }

   private:
	void run(const char* name, bool background);
	void rethrow();

	const size_t max_pending_;
	std::mutex m_;
	std::condition_variable wake_, done_;
	std::deque<std::function<void()>> jobs_;
	bool busy_ = false, stop_ = false;
	std::exception_ptr error_;
	std::thread worker_;
};

}  // namespace forest_slam::core
