#include <forest_slam/odometry/map_inserter.h>

namespace forest_slam::odometry
{
MapInserter::MapInserter(map::CForestMap& map, size_t max_pending)
    : map_(map), max_pending_(max_pending)
{
	if (max_pending_ > 0) worker_ = std::thread([this] { run(); });
}

MapInserter::~MapInserter()
{
	if (!worker_.joinable()) return;
	{
		std::lock_guard<std::mutex> lk(m_);
		stop_ = true;
	}
	wake_.notify_all();
	worker_.join();
}

void MapInserter::rethrow()
{
	if (!error_) return;
	auto e = error_;
	error_ = nullptr;
	std::rethrow_exception(e);
}

void MapInserter::push(std::vector<Eigen::Vector3f> edges,
                       std::vector<Eigen::Vector3f> planar,
                       const Eigen::Isometry3d& sensor_to_map)
{
	if (max_pending_ == 0)
	{
		map_.insertFeatures(edges, planar, sensor_to_map);
		return;
	}
	std::unique_lock<std::mutex> lk(m_);
	done_.wait(lk, [&] { return jobs_.size() < max_pending_ || error_; });
	rethrow();
	jobs_.push_back({std::move(edges), std::move(planar), sensor_to_map});
	lk.unlock();
	wake_.notify_one();
}

void MapInserter::flush()
{
	if (max_pending_ == 0) return;
	std::unique_lock<std::mutex> lk(m_);
	done_.wait(lk, [&] { return (jobs_.empty() && !busy_) || error_; });
	rethrow();
}

void MapInserter::run()
{
	std::unique_lock<std::mutex> lk(m_);
	for (;;)
	{
		wake_.wait(lk, [&] { return stop_ || !jobs_.empty(); });
		if (jobs_.empty()) return;  // stop_ with nothing left
		Job job = std::move(jobs_.front());
		jobs_.pop_front();
		busy_ = true;
		lk.unlock();
		std::exception_ptr err;
		try
		{
			map_.insertFeatures(job.edges, job.planar, job.pose);
		}
		catch (...)
		{
			err = std::current_exception();
		}
		lk.lock();
		busy_ = false;
		if (err && !error_) error_ = err;
		done_.notify_all();
	}
}

}  // namespace forest_slam::odometry
