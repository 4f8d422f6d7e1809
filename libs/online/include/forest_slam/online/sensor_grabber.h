#pragma once
// One thread per sensor, as in rawlog-grabber: call the MRPT driver's
// doProcess() at its process_rate and hand every observation it produced,
// with the moment it was collected, to the sink.
#include <forest_slam/online/online_config.h>
#include <forest_slam/online/velodyne_udp.h>

#include <mrpt/obs/CObservation.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <thread>

namespace forest_slam::online
{
using SteadyClock = std::chrono::steady_clock;

class SensorGrabber
{
   public:
	using Sink = std::function<void(const mrpt::obs::CObservation::Ptr&,
	                                SteadyClock::time_point captured)>;
	SensorGrabber(SensorDeclaration decl, Sink sink);
	~SensorGrabber();  ///< stop()
	SensorGrabber(const SensorGrabber&) = delete;
	SensorGrabber& operator=(const SensorGrabber&) = delete;

	/** initialize() on the calling thread (errors such as a UDP port in use
	 * throw std::runtime_error naming the section), then starts grabbing. */
	void start();
	/** Stops grabbing and joins the thread. Our Velodyne receiver then
	 * hands over the revolution in progress; an MRPT driver keeps what it
	 * had not completed. */
	void stop();

	/** A file replay (CVelodyneScanner pcap_input) reached its end. */
	bool exhausted() const { return exhausted_; }
	uint64_t observations() const { return observations_; }
	const SensorDeclaration& declaration() const { return decl_; }

   private:
	SensorDeclaration decl_;
	Sink sink_;
	std::unique_ptr<VelodyneUdpReceiver> udp_;  ///< decl_.velodyne_udp
	std::thread thread_;
	std::atomic<bool> stop_{false}, exhausted_{false};
	std::atomic<uint64_t> observations_{0};
	void run();
};

}  // namespace forest_slam::online
