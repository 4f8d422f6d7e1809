#include <forest_slam/core/atomic_file.h>
#include <forest_slam/core/log.h>
#include <forest_slam/online/live_source.h>
#include <forest_slam/pipeline/mapping_pipeline.h>

#include <mrpt/obs/CObservationVelodyneScan.h>

#include <algorithm>
#include <cstdio>
#include <iomanip>
#include <sstream>

namespace forest_slam::online
{
namespace
{
std::string jsonText(const std::string& s)
{
	std::string o;
	for (char c : s)
		if (c == '"' || c == '\\')
			o += std::string("\\") + c;
		else if (static_cast<unsigned char>(c) >= 0x20)
			o += c;
	return o;
}
}  // namespace

Spread Spread::of(std::vector<double> v)
{
	Spread s;
	if (v.empty()) return s;
	std::sort(v.begin(), v.end());
	s.median = v[v.size() / 2];
	s.p95 = v[std::min(v.size() - 1, static_cast<size_t>(0.95 * v.size()))];
	s.max = v.back();
	return s;
}

LiveSource::LiveSource(const OnlineConfig& cfg, const std::string& out_dir)
    : cfg_(cfg)
{
	core::ensureDirectory(out_dir);
	recorder_ = std::make_unique<RawRecorder>(out_dir + "/raw.rawlog",
	                                          cfg.online.record_compress_level,
	                                          cfg.online.record_flush_period_s);
	for (const auto& s : cfg_.sensors)
		grabbers_.push_back(std::make_unique<SensorGrabber>(
		    s, [this](const mrpt::obs::CObservation::Ptr& o,
		              SteadyClock::time_point t) { onObservation(o, t); }));
}

LiveSource::~LiveSource()
{
	stopGrabbing();
	// recorder_'s destructor writes what is queued and closes the file.
}

void LiveSource::start()
{
	last_arrival_ = last_status_ = SteadyClock::now();
	{
		std::lock_guard<std::mutex> lk(mu_);
		grabbing_ = true;
	}
	for (auto& g : grabbers_) g->start();
}

void LiveSource::onObservation(const mrpt::obs::CObservation::Ptr& obs,
                               SteadyClock::time_point t)
{
	const bool scan = obs->sensorLabel == cfg_.mapping.pipeline.lidar_label;
	const auto* vel =
	    dynamic_cast<const mrpt::obs::CObservationVelodyneScan*>(obs.get());
	{
		std::lock_guard<std::mutex> lk(mu_);
		// Recorded first and unconditionally, under the queue's lock so that
		// raw.rawlog has the pipeline's order (an offline re-run matches).
		recorder_->record(obs);
		stats_.observations_captured++;
		if (vel) stats_.velodyne_packets += vel->scan_packets.size();
		last_arrival_ = t;
		if (scan)
		{
			stats_.scans_captured++;
			if (stats_.queue_now >= cfg_.online.queue_capacity_scans)
			{
				// Even light scans cannot keep up: drop the oldest waiting one.
				const auto it =
				    std::find_if(queue_.begin(), queue_.end(),
				                 [](const Item& i) { return i.scan; });
				queue_.erase(it);
				stats_.queue_now--;
				stats_.scans_dropped++;
			}
			stats_.queue_now++;
			stats_.queue_max = std::max(stats_.queue_max, stats_.queue_now);
		}
		queue_.push_back({obs, t, scan});
	}
	cv_.notify_one();
}

bool LiveSource::allExhausted() const
{
	for (const auto& g : grabbers_)
		if (!g->exhausted()) return false;
	return true;
}

void LiveSource::stopGrabbing()
{
	{
		std::lock_guard<std::mutex> lk(mu_);
		if (!grabbing_) return;
		grabbing_ = false;
	}
	for (auto& g : grabbers_) g->stop();  // outside the lock: they push
	std::lock_guard<std::mutex> lk(mu_);
	FS_LOG_INFO("grabbing stopped; " << queue_.size()
	                                 << " observations left to process");
}

mrpt::obs::CObservation::Ptr LiveSource::next()
{
	// A stop signal ends grabbing at once, even while the queue is long.
	if (pipeline::stopSignal() != 0) stopGrabbing();
	for (;;)
	{
		maybePrintStatus();
		bool stop_now = false;
		{
			std::unique_lock<std::mutex> lk(mu_);
			if (!grabbing_ && !queue_.empty() &&
			    pipeline::stopSignalCount() >= 2)
			{
				// A second Ctrl-C: the user does not want to wait for the
				// drain. What is left is in raw.rawlog already.
				FS_LOG_WARN("second stop signal: "
				            << queue_.size()
				            << " queued observations not "
				               "processed (they are in raw.rawlog)");
				stats_.scans_unprocessed += stats_.queue_now;
				stats_.queue_now = 0;
				queue_.clear();
			}
			if (!queue_.empty())
			{
				current_ = std::move(queue_.front());
				queue_.pop_front();
				if (current_.scan) stats_.queue_now--;
				return current_.obs;
			}
			if (!grabbing_) return nullptr;  // stopped and drained
			const double idle = std::chrono::duration<double>(
			                        SteadyClock::now() - last_arrival_)
			                        .count();
			stop_now = pipeline::stopSignal() != 0 || allExhausted() ||
			           (cfg_.online.idle_timeout_s > 0 &&
			            idle > cfg_.online.idle_timeout_s);
			if (!stop_now) cv_.wait_for(lk, std::chrono::milliseconds(100));
		}
		if (stop_now) stopGrabbing();
	}
}

void LiveSource::willProcess(const mrpt::obs::CObservation&,
                             pipeline::MappingPipeline& p)
{
	if (!current_.scan) return;
	std::lock_guard<std::mutex> lk(mu_);
	p.setLightScans(stats_.queue_now > cfg_.online.light_above_queued_scans);
}

void LiveSource::processed(const mrpt::obs::CObservation&,
                           const pipeline::MappingPipeline& p)
{
	if (current_.scan) awaiting_pose_.push_back(current_.captured);
	current_ = {};
	collectLatencies(p);
	maybePrintStatus();
}

void LiveSource::collectLatencies(const pipeline::MappingPipeline& p)
{
	// A scan is posed (or skipped) when the pipeline is done with it, which
	// may be a few observations later (the odometry waits for the IMU
	// samples covering its sweep): latencies go to the scans in order.
	const uint64_t done = p.stats().scans_in - p.scansPending();
	const auto now = SteadyClock::now();
	{
		std::lock_guard<std::mutex> lk(mu_);
		while (scans_done_ < done && !awaiting_pose_.empty())
		{
			stats_.latency_ms.push_back(
			    std::chrono::duration<double, std::milli>(
			        now - awaiting_pose_.front())
			        .count());
			awaiting_pose_.pop_front();
			scans_done_++;
		}
		stats_.scans_processed = scans_done_;
		stats_.scans_light = p.stats().scans_light;
	}
}

void LiveSource::finish(const pipeline::MappingPipeline& p)
{
	collectLatencies(p);  // after p.finish(): the last waiting scans
	stopGrabbing();
	try
	{
		recorder_->close();
	}
	catch (const std::exception& e)
	{
		recording_error_ = e.what();
		FS_LOG_ERROR("raw recording: " << e.what());
	}
	maybePrintStatus(true);
}

LiveStats LiveSource::stats() const
{
	std::lock_guard<std::mutex> lk(mu_);
	LiveStats s = stats_;
	s.recorded = recorder_->recorded();
	s.recorded_bytes = recorder_->bytes();
	return s;
}

std::string LiveSource::statusLine() const
{
	const auto s = stats();
	const auto lat = Spread::of(s.latency_ms);
	std::ostringstream os;
	os << std::fixed << std::setprecision(0) << "scans " << s.scans_processed
	   << " (light " << s.scans_light << ", dropped " << s.scans_dropped
	   << ") | latency median " << lat.median << " ms, max " << lat.max
	   << " ms | queue " << s.queue_now << " | recorded " << s.recorded
	   << " obs, " << std::setprecision(1) << s.recorded_bytes / 1e6 << " MB";
	return os.str();
}

void LiveSource::maybePrintStatus(bool force)
{
	const double period = cfg_.online.status_period_s;
	if (!force && (period <= 0 || std::chrono::duration<double>(
	                                  SteadyClock::now() - last_status_)
	                                      .count() < period))
		return;
	last_status_ = SteadyClock::now();
	FS_LOG_INFO("status: " << statusLine());
}

std::vector<std::string> LiveSource::writeOutputs(const std::string& out_dir)
{
	const auto s = stats();
	const auto lat = Spread::of(s.latency_ms);
	const std::string path = out_dir + "/online_stats.json";
	core::writeFileAtomically(
	    path,
	    [&](std::ostream& os)
	    {
		    os << "{\n  \"observations_captured\": " << s.observations_captured
		       << ",\n  \"observations_recorded\": " << s.recorded
		       << ",\n  \"recorded_bytes\": " << s.recorded_bytes
		       << ",\n  \"recording_error\": \"" << jsonText(recording_error_)
		       << "\",\n  \"velodyne_packets\": " << s.velodyne_packets
		       << ",\n  \"scans_captured\": " << s.scans_captured
		       << ",\n  \"scans_processed\": " << s.scans_processed
		       << ",\n  \"scans_light\": " << s.scans_light
		       << ",\n  \"scans_dropped\": " << s.scans_dropped
		       << ",\n  \"scans_unprocessed\": " << s.scans_unprocessed
		       << ",\n  \"queue_max_scans\": " << s.queue_max
		       << ",\n  \"latency_ms\": {\"median\": " << lat.median
		       << ", \"p95\": " << lat.p95 << ", \"max\": " << lat.max
		       << "},\n  \"sensors\": [";
		    for (size_t i = 0; i < grabbers_.size(); i++)
		    {
			    const auto& d = grabbers_[i]->declaration();
			    os << (i ? ", " : "") << "{\"section\": \"" << d.section
			       << "\", \"driver\": \"" << d.driver << "\", \"label\": \""
			       << d.label
			       << "\", \"observations\": " << grabbers_[i]->observations()
			       << "}";
		    }
		    os << "]\n}\n";
	    });
	return {path};
}

std::string LiveSource::describe() const
{
	std::string d = "live sensors";
	for (const auto& s : cfg_.sensors)
		d += " [" + s.section + "] " + s.driver + " '" + s.label + "'";
	return d + " (recording " + recorder_->path() + ")";
}

}  // namespace forest_slam::online
