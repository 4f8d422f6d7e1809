#pragma once
// Live sensors as an ObservationSource: one grabbing thread per sensor, every
// observation recorded to raw.rawlog at once, and a bounded queue into the
// mapping pipeline. If the pipeline falls behind, waiting scans go through it
// light (motion-model pose, no registration or map insertion) until it
// caught up; only beyond queue_capacity_scans are scans dropped from the
// pipeline's queue. The recording never drops anything.
#include <forest_slam/online/online_config.h>
#include <forest_slam/online/raw_recorder.h>
#include <forest_slam/online/sensor_grabber.h>
#include <forest_slam/pipeline/observation_source.h>

#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace forest_slam::online
{
struct LiveStats
{
	uint64_t observations_captured = 0;
	uint64_t scans_captured = 0;
	uint64_t scans_processed =
	    0;  ///< went through the pipeline (full or light)
	uint64_t scans_light = 0;
	uint64_t scans_dropped =
	    0;  ///< from the pipeline's queue, not the recording
	/** Left in the queue by a second stop signal (still in raw.rawlog). */
	uint64_t scans_unprocessed = 0;
	uint64_t queue_max = 0;  ///< most scans ever waiting
	uint64_t queue_now = 0;
	std::vector<double> latency_ms;  ///< capture -> pose, per processed scan
	uint64_t recorded = 0, recorded_bytes = 0;
	/** Velodyne data packets in the captured scans (compare with what the
	 * sensor sent: UDP loss before the driver is invisible otherwise). */
	uint64_t velodyne_packets = 0;
};

/** Median / p95 / max of a sample (0 when empty). */
struct Spread
{
	double median = 0, p95 = 0, max = 0;
	static Spread of(std::vector<double> v);
};

class LiveSource : public pipeline::ObservationSource
{
   public:
	/** Creates out_dir/raw.rawlog (never overwrites one) and the grabbers;
	 * nothing is grabbed before start(). */
	LiveSource(const OnlineConfig& cfg, const std::string& out_dir);
	~LiveSource() override;

	/** Starts every sensor; throws std::runtime_error naming the sensor
	 * that cannot start (port in use, device missing). */
	void start();

	mrpt::obs::CObservation::Ptr next() override;
	bool drainOnStop() const override { return true; }
	bool live() const override { return true; }
	void willProcess(const mrpt::obs::CObservation& obs,
	                 pipeline::MappingPipeline& p) override;
	void processed(const mrpt::obs::CObservation& obs,
	               const pipeline::MappingPipeline& p) override;
	void finish(const pipeline::MappingPipeline& p) override;
	/** online_stats.json (latency, queue, drops, recording). */
	std::vector<std::string> writeOutputs(const std::string& out_dir) override;
	std::string describe() const override;

	LiveStats stats() const;
	/** "scans 120 (light 3, dropped 0) | latency median 85 ms, max 410 ms |
	 * queue 2 | recorded 1290 obs, 51.2 MB" */
	std::string statusLine() const;
	/** Empty unless writing raw.rawlog failed. */
	const std::string& recordingError() const { return recording_error_; }

   private:
	struct Item
	{
		mrpt::obs::CObservation::Ptr obs;
		SteadyClock::time_point captured;
		bool scan = false;
	};
	OnlineConfig cfg_;
	std::unique_ptr<RawRecorder> recorder_;
	std::vector<std::unique_ptr<SensorGrabber>> grabbers_;
	mutable std::mutex mu_;
	std::condition_variable cv_;
	std::deque<Item> queue_;
	LiveStats stats_;
	SteadyClock::time_point last_arrival_, last_status_;
	bool grabbing_ = false;
	Item current_;
	std::string recording_error_;

	void onObservation(const mrpt::obs::CObservation::Ptr& obs,
	                   SteadyClock::time_point t);
	void stopGrabbing();
	bool allExhausted() const;
	void maybePrintStatus(bool force = false);
	/** Latencies of the scans the pipeline has posed since the last call. */
	void collectLatencies(const pipeline::MappingPipeline& p);
	std::deque<SteadyClock::time_point> awaiting_pose_;
	uint64_t scans_done_ = 0;
};

}  // namespace forest_slam::online
