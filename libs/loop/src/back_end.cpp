#include <forest_slam/core/log.h>
#include <forest_slam/core/memory.h>
#include <forest_slam/loop/back_end.h>
#include <forest_slam/loop/levelling.h>
#include <pthread.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <stdexcept>
#include <string>

namespace forest_slam::loop
{
namespace
{
double msSince(std::chrono::steady_clock::time_point t)
{
	return std::chrono::duration<double, std::milli>(
	           std::chrono::steady_clock::now() - t)
	    .count();
}

double threadCpuMs()
{
	timespec ts{};
	if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts) != 0) return 0;
	return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}
}  // namespace

BackEnd::BackEnd(const LoopOptions& o, bool threaded,
                 std::shared_ptr<core::SpillFile> spill)
    : o_(o), threaded_(threaded), spill_(std::move(spill))
{
	if (threaded_)
		worker_ = std::thread(
		    [this]
		    {
			    pthread_setname_np(pthread_self(), "fs-backend");
			    core::runInBackground();
			    run();
		    });
}

BackEnd::~BackEnd()
{
	{
		std::lock_guard<std::mutex> lk(mutex_);
		stop_ = true;
	}
	cv_.notify_all();
	if (worker_.joinable()) worker_.join();
}

void BackEnd::rethrowLocked() const
{
	if (!error_) return;
	try
	{
		std::rethrow_exception(error_);
	}
	catch (const std::exception& e)
	{
		throw std::runtime_error(std::string("back-end: ") + e.what());
	}
}

size_t BackEnd::addKeyframe(Keyframe kf)
{
	Item it;
	{
		std::lock_guard<std::mutex> lk(mutex_);
		rethrowLocked();
		cloud_bytes_ += kf.cloud.capacity() * sizeof(Eigen::Vector3f);
		kf.id = next_id_++;
		it.kf = std::move(kf);
		if (threaded_) queue_.push_back(std::move(it));
	}
	if (threaded_)
		cv_.notify_all();
	else
		process(it);
	return next_id_ - 1;
}

void BackEnd::addGnss(const GnssFix& f)
{
	Item it;
	it.gnss = f;
	if (!threaded_)
	{
		process(it);
		return;
	}
	{
		std::lock_guard<std::mutex> lk(mutex_);
		rethrowLocked();
		queue_.push_back(std::move(it));
	}
	cv_.notify_all();
}

bool BackEnd::resultAt(size_t id, Poses& out)
{
	const auto t = std::chrono::steady_clock::now();
	std::unique_lock<std::mutex> lk(mutex_);
	cv_.wait(lk, [&] { return processed_ >= static_cast<long>(id) || error_; });
	wait_ms_ += msSince(t);
	rethrowLocked();
	auto it = results_.find(id);
	if (it == results_.end()) return false;
	out = std::move(it->second);
	results_.erase(results_.begin(), std::next(it));
	return true;
}

void BackEnd::run()
{
	for (;;)
	{
		Item it;
		{
			std::unique_lock<std::mutex> lk(mutex_);
			cv_.wait(lk, [&] { return stop_ || !queue_.empty(); });
			if (queue_.empty())  // stop requested, nothing left
			{
				stats_.worker_cpu_ms = threadCpuMs();
				return;
			}
			it = std::move(queue_.front());
			queue_.pop_front();
		}
		try
		{
			process(it);
		}
		catch (...)
		{
			// An exception leaving the thread would abort the process and
			// lose the whole run: the caller gets it instead.
			std::lock_guard<std::mutex> lk(mutex_);
			error_ = std::current_exception();
			queue_.clear();
			stats_.worker_cpu_ms = threadCpuMs();
			cv_.notify_all();
			return;
		}
	}
}

void BackEnd::process(Item& it)
{
	if (it.gnss)
	{
		const auto& f = *it.gnss;
		if (f.keyframe < graph_.size())
		{
			GnssFactor g;
			g.node = f.keyframe;
			g.antenna_in_node = f.antenna_in_keyframe;
			g.enu = f.enu;
			g.sigma = f.sigma;
			graph_.addGnss(g);
			stats_.gnss_fixes++;
			gnss_since_opt_++;
		}
		return;
	}
	Keyframe& kf = *it.kf;
	const size_t id = kf.id;
	processKeyframe(kf);
	std::lock_guard<std::mutex> lk(mutex_);
	processed_ = static_cast<long>(id);
	cv_.notify_all();
}

void BackEnd::processKeyframe(Keyframe& kf)
{
	const size_t id = kf.id;
	const double travel_edge =
	    kf.odom_edge.translation().norm();  // for the edge noise
	graph_.addNode(id == 0 ? Eigen::Isometry3d::Identity() * kf.odom_edge
	                       : graph_.pose(id - 1) * kf.odom_edge);
	if (id > 0)
	{
		RelativeFactor f;
		f.a = id - 1;
		f.b = id;
		f.T_ab = kf.odom_edge;
		f.sqrt_information = sqrtInformation(
		    o_.odom_sigma_t_m + o_.odom_sigma_t_per_m * travel_edge,
		    (o_.odom_sigma_r_deg + o_.odom_sigma_r_deg_per_m * travel_edge) *
		        M_PI / 180);
		graph_.addFactor(f);
	}
	kfs_.push_back(std::move(kf));
	cloud_disk_.emplace_back();
	stats_.keyframes++;
	if (o_.descriptor)
	{
		Poses recent(id + 1);
		const size_t m = static_cast<size_t>(o_.descriptor_keyframes);
		for (size_t i = id >= m ? id - m : 0; i <= id; i++)
			recent[i] = graph_.pose(i);
		descriptors_.push_back(keyframeDescriptor(kfs_, recent, id, o_));
	}

	bool changed = false;
	if (id >= next_attempt_ &&
	    id % static_cast<size_t>(o_.detect_every_keyframes) == 0)
	{
		Poses poses(graph_.size());
		for (size_t i = 0; i < graph_.size(); i++) poses[i] = graph_.pose(i);
		const auto t = std::chrono::steady_clock::now();
		// Geometric candidates first, then the descriptor's best matches
		// elsewhere.
		const auto near = loopCandidates(kfs_, poses, id, o_);
		std::vector<std::pair<size_t, std::optional<DescriptorMatch>>> cands;
		for (size_t j : near) cands.emplace_back(j, std::nullopt);
		if (o_.descriptor)
			for (const auto& d :
			     descriptorCandidates(kfs_, poses, descriptors_, id, near, o_))
				cands.emplace_back(d.from, d.match);
		for (const auto& [j, match] : cands)
		{
			stats_.candidates++;
			stats_.descriptor_candidates += match.has_value();
			const size_t m = static_cast<size_t>(o_.submap_keyframes);
			loadClouds(j >= m ? j - m : 0, std::min(j + m, id));
			Closure c = verifyClosure(kfs_, poses, j, id, o_,
			                          match ? &*match : nullptr);
			closures_.push_back(c);
			FS_LOG_DEBUG("loop "
			             << j << " -> " << id << (match ? " (descriptor)" : "")
			             << ": " << (c.accepted ? "accepted" : c.reason)
			             << " overlap " << c.overlap << " rmse " << c.rmse_m
			             << " chi2 " << c.chi2);
			if (!c.accepted) continue;
			RelativeFactor f;
			f.a = j;
			f.b = id;
			f.T_ab = c.T;
			f.sqrt_information = sqrtInformation(
			    o_.loop_sigma_t_m, o_.loop_sigma_r_deg * M_PI / 180);
			f.robust = false;  // verified hard; a kernel would ignore big drift
			graph_.addFactor(f);
			stats_.closures++;
			stats_.descriptor_closures += match.has_value();
			changed = true;
			next_attempt_ =
			    id + static_cast<size_t>(o_.closure_spacing_keyframes);
			break;
		}
		stats_.verify_ms += msSince(t);
	}
	spillOldClouds(id);
	// GNSS: re-optimise when fixes arrived (not at every keyframe).
	if (gnss_since_opt_ > 0 &&
	    id % static_cast<size_t>(o_.detect_every_keyframes) == 0)
		changed = true;
	if (changed && optimise())
	{
		Poses out(graph_.size());
		for (size_t i = 0; i < graph_.size(); i++) out[i] = graph_.pose(i);
		std::lock_guard<std::mutex> lk(mutex_);
		results_[id] = std::move(out);
	}
}

void BackEnd::loadClouds(size_t first, size_t last)
{
	if (!spill_) return;
	for (size_t i = first; i <= last && i < kfs_.size(); i++)
	{
		const auto& d = cloud_disk_[i];
		if (!d.written || !kfs_[i].cloud.empty() || d.count == 0) continue;
		spill_->readVector(d.offset, d.count, kfs_[i].cloud);
		cloud_bytes_ += d.count * sizeof(Eigen::Vector3f);
	}
}

void BackEnd::spillOldClouds(size_t newest)
{
	if (!spill_) return;
	// The coming keyframes read the last descriptor_keyframes clouds
	// (descriptor) and the last submap_keyframes (ICP source).
	const size_t keep = static_cast<size_t>(std::max(o_.submap_keyframes,
	                                                 o_.descriptor_keyframes)) +
	                    1;
	if (newest < keep) return;
	// Every cloud up to newest - keep is out of memory after each call, so
	// only the one that just aged out, and those read back for candidates,
	// are in memory here.
	for (size_t i = 0; i + keep <= newest; i++)
	{
		auto& c = kfs_[i].cloud;
		if (c.empty()) continue;
		auto& d = cloud_disk_[i];
		if (!d.written)
		{
			d.offset = spill_->appendVector(c);
			d.count = c.size();
			d.written = true;
			cloud_bytes_spilled_ += d.count * sizeof(Eigen::Vector3f);
		}
		cloud_bytes_ -= c.capacity() * sizeof(Eigen::Vector3f);
		std::vector<Eigen::Vector3f>().swap(c);
	}
}

bool BackEnd::optimise()
{
	const auto t = std::chrono::steady_clock::now();
	const bool ok = graph_.optimize(o_.gnss_min_baseline_m, o_.gnss_gate_sigma);
	gnss_since_opt_ = 0;
	stats_.optimisations++;
	stats_.optimise_ms += msSince(t);
	size_t outliers = 0;
	for (const auto& g : graph_.gnss()) outliers += g.outlier;
	stats_.gnss_outliers = outliers;
	return ok;
}

void BackEnd::finish()
{
	if (threaded_)
	{
		{
			std::lock_guard<std::mutex> lk(mutex_);
			stop_ = true;
		}
		cv_.notify_all();
		if (worker_.joinable()) worker_.join();
		std::lock_guard<std::mutex> lk(mutex_);
		rethrowLocked();
	}
	if (stats_.closures > 0 || !graph_.gnss().empty()) optimise();
	if (o_.level_with_imu && !graph_.hasEnu()) level();
}

void BackEnd::level()
{
	std::vector<Eigen::Matrix3d> R;
	std::vector<std::optional<Eigen::Vector3d>> up;
	for (size_t i = 0; i < graph_.size() && i < kfs_.size(); i++)
	{
		R.push_back(graph_.pose(i).linear());
		up.push_back(kfs_[i].up);
	}
	const Levelling L = estimateLevelling(R, up);
	if (!L.ok) return;
	// A rotation about the map origin (the first lidar position): every
	// keyframe moves with it, and the pipeline's final correction takes
	// the maps along.
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	T.linear() = L.R;
	for (size_t i = 0; i < graph_.size(); i++)
		graph_.setPose(i, T * graph_.pose(i));
	stats_.levelled = true;
	stats_.levelling_deg = L.tilt_deg;
	stats_.levelling_rms_deg = L.residual_rms_deg;
	stats_.levelling_keyframes = L.used;
}

Poses BackEnd::poses() const
{
	Poses out(graph_.size());
	for (size_t i = 0; i < graph_.size(); i++) out[i] = graph_.pose(i);
	return out;
}

std::vector<double> BackEnd::keyframeStamps() const
{
	std::vector<double> t;
	for (const auto& k : kfs_) t.push_back(k.stamp_s);
	return t;
}

std::vector<Closure> BackEnd::closures() const
{
	return closures_;
}
BackEndStats BackEnd::stats() const
{
	BackEndStats s = stats_;
	s.wait_ms = wait_ms_;
	return s;
}
std::optional<MapToEnu> BackEnd::mapToEnu() const
{
	if (!graph_.hasEnu()) return std::nullopt;
	return graph_.mapToEnu();
}

}  // namespace forest_slam::loop
