#include <forest_slam/core/parallel_for.h>

#include <pthread.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <exception>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace forest_slam::core
{
namespace
{
using RangeFn = std::function<void(size_t, size_t, int)>;

/** The helper threads of one calling thread. A loop is "open" from its
 * start until the caller has run out of chunks; a helper that wakes later
 * sits it out, so the caller never waits for a thread still being woken. */
class HelperPool
{
   public:
	explicit HelperPool(int helpers)
	{
		// Named after their owner (the mapping thread's: fs-helper), so
		// that top -H and run_summary.json tell whose loops they run; they
		// inherit its priority (Linux: a thread starts at its creator's
		// nice value).
		char owner[16] = {};
		pthread_getname_np(pthread_self(), owner, sizeof owner);
		std::string name = "fs-helper";
		if (std::string(owner).rfind("fs-", 0) == 0)
			name = (std::string(owner) + "-h").substr(0, 15);
		for (int i = 0; i < helpers; i++)
			threads_.emplace_back(
			    [this, i, name]
			    {
				    pthread_setname_np(pthread_self(), name.c_str());
				    loop(i + 1);
			    });
	}
	~HelperPool()
	{
		{
			std::lock_guard<std::mutex> lk(m_);
			stop_ = true;
		}
		wake_.notify_all();
		for (auto& t : threads_) t.join();
	}
	int helpers() const { return static_cast<int>(threads_.size()); }

	void run(size_t n, int workers, size_t chunk, const RangeFn& fn)
	{
		{
			std::lock_guard<std::mutex> lk(m_);
			fn_ = &fn;
			n_ = n;
			chunk_ = chunk;
			next_.store(0);
			wanted_ = workers - 1;
			open_ = true;
			generation_++;
		}
		wake_.notify_all();
		std::exception_ptr mine;
		try
		{
			chunks(0);
		}
		catch (...)
		{
			mine = std::current_exception();
			next_.store(n_);  // the others stop after their chunk
		}
		std::unique_lock<std::mutex> lk(m_);
		open_ = false;
		idle_.wait(lk, [&] { return active_ == 0; });
		fn_ = nullptr;
		std::exception_ptr theirs = error_;
		error_ = nullptr;
		lk.unlock();
		if (mine) std::rethrow_exception(mine);
		if (theirs) std::rethrow_exception(theirs);
	}

   private:
	void chunks(int worker)
	{
		for (size_t b; (b = next_.fetch_add(chunk_)) < n_;)
			(*fn_)(b, std::min(n_, b + chunk_), worker);
	}

	void loop(int worker)
	{
		uint64_t seen = 0;
		std::unique_lock<std::mutex> lk(m_);
		for (;;)
		{
			wake_.wait(lk,
			           [&] { return stop_ || (open_ && generation_ != seen); });
			if (stop_) return;
			seen = generation_;
			if (worker > wanted_) continue;
			active_++;
			lk.unlock();
			try
			{
				chunks(worker);
			}
			catch (...)
			{
				next_.store(n_);
				const std::lock_guard<std::mutex> g(m_);
				if (!error_) error_ = std::current_exception();
			}
			lk.lock();
			if (--active_ == 0) idle_.notify_all();
		}
	}

	std::mutex m_;
	std::condition_variable wake_, idle_;
	const RangeFn* fn_ = nullptr;
	size_t n_ = 0, chunk_ = 1;
	std::atomic<size_t> next_{0};
	uint64_t generation_ = 0;
	int wanted_ = 0, active_ = 0;
	bool open_ = false, stop_ = false;
	std::exception_ptr error_;
	std::vector<std::thread> threads_;
};
}  // namespace

void parallelRanges(size_t n, int threads, size_t chunk, const RangeFn& fn)
{
	chunk = std::max<size_t>(1, chunk);
	if (threads <= 1 || n <= chunk)
	{
		for (size_t b = 0; b < n; b += chunk) fn(b, std::min(n, b + chunk), 0);
		return;
	}
	// At most one chunk per worker is useful.
	const int workers =
	    static_cast<int>(std::min<size_t>(threads, (n + chunk - 1) / chunk));
	thread_local std::unique_ptr<HelperPool> pool;
	if (!pool || pool->helpers() < workers - 1)
	{
		pool.reset();
		pool = std::make_unique<HelperPool>(workers - 1);
	}
	pool->run(n, workers, chunk, fn);
}

}  // namespace forest_slam::core
