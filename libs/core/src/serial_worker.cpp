#include <forest_slam/core/memory.h>
#include <forest_slam/core/serial_worker.h>

#include <pthread.h>

namespace forest_slam::core
{
SerialWorker::SerialWorker(size_t max_pending, const char* name,
                           bool background)
    : max_pending_(max_pending)
{
	if (max_pending_ > 0)
		worker_ =
		    std::thread([this, name, background] { run(name, background); });
}

SerialWorker::~SerialWorker()
{
	if (!worker_.joinable()) return;
	{
		std::lock_guard<std::mutex> lk(m_);
		stop_ = true;
	}
	wake_.notify_all();
	worker_.join();
}

void SerialWorker::rethrow()
{
	if (!error_) return;
	auto e = error_;
	error_ = nullptr;
	std::rethrow_exception(e);
}

void SerialWorker::push(std::function<void()> job)
{
	if (max_pending_ == 0)
	{
		job();
		return;
	}
	std::unique_lock<std::mutex> lk(m_);
	done_.wait(lk, [&] { return jobs_.size() < max_pending_ || error_; });
	rethrow();
	jobs_.push_back(std::move(job));
	lk.unlock();
	wake_.notify_one();
}

void SerialWorker::flush()
{
	if (max_pending_ == 0) return;
	std::unique_lock<std::mutex> lk(m_);
	done_.wait(lk, [&] { return (jobs_.empty() && !busy_) || error_; });
	rethrow();
}

void SerialWorker::run(const char* name, bool background)
{
	pthread_setname_np(pthread_self(), name);  // a longer name is refused
	if (background) runInBackground();
	std::unique_lock<std::mutex> lk(m_);
	for (;;)
	{
		wake_.wait(lk, [&] { return stop_ || !jobs_.empty(); });
		if (jobs_.empty()) return;  // stop_ with nothing left
		std::function<void()> job = std::move(jobs_.front());
		jobs_.pop_front();
		busy_ = true;
		lk.unlock();
		std::exception_ptr err;
		try
		{
			job();
		}
		catch (...)
		{
			err = std::current_exception();
		}
		lk.lock();
		busy_ = false;
		if (err && !error_)
		{
			error_ = err;
			jobs_.clear();  // they would build on the failed one
		}
		done_.notify_all();
	}
}

}  // namespace forest_slam::core
