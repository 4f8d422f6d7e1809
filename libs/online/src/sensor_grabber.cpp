#include <forest_slam/core/log.h>
#include <forest_slam/online/sensor_grabber.h>

#include <mrpt/hwdrivers/CGenericSensor.h>

#include <stdexcept>

namespace forest_slam::online
{
SensorGrabber::SensorGrabber(SensorDeclaration decl, Sink sink)
    : decl_(std::move(decl)), sink_(std::move(sink))
{
}

SensorGrabber::~SensorGrabber()
{
	stop();
}

void SensorGrabber::start()
{
	try
	{
		if (decl_.velodyne_udp)
		{
			udp_ = std::make_unique<VelodyneUdpReceiver>(*decl_.velodyne_udp);
			udp_->open();
		}
		else
			decl_.sensor->initialize();
	}
	catch (const std::exception& e)
	{
		std::string what = e.what();
		if (what.size() > 400) what = what.substr(0, 400) + "...";
		throw std::runtime_error("sensor [" + decl_.section + "] (" +
		                         decl_.driver + ") failed to start: " + what);
	}
	if (udp_)
		FS_LOG_INFO("sensor [" << decl_.section << "] " << decl_.driver << " '"
		                       << decl_.label << "': UDP ports "
		                       << decl_.velodyne_udp->data_port << "/"
		                       << decl_.velodyne_udp->position_port
		                       << ", forest-slam receiver, grabbing at "
		                       << decl_.process_rate_hz << " Hz");
	else
		FS_LOG_INFO("sensor [" << decl_.section << "] " << decl_.driver << " '"
		                       << decl_.label << "' grabbing at "
		                       << decl_.process_rate_hz << " Hz");
	thread_ = std::thread([this] { run(); });
}

void SensorGrabber::stop()
{
	stop_ = true;
	if (!thread_.joinable()) return;
	thread_.join();
	if (udp_)
	{
		std::vector<mrpt::obs::CObservation::Ptr> last;
		udp_->flush(last);
		for (const auto& o : last)
		{
			sink_(o, SteadyClock::now());
			observations_++;
		}
	}
}

void SensorGrabber::run()
{
	using mrpt::hwdrivers::CGenericSensor;
	const auto period = std::chrono::duration_cast<SteadyClock::duration>(
	    std::chrono::duration<double>(1.0 / decl_.process_rate_hz));
	auto& sensor = *decl_.sensor;
	std::vector<mrpt::obs::CObservation::Ptr> received;
	while (!stop_)
	{
		const auto t0 = SteadyClock::now();
		if (udp_)
		{
			received.clear();
			try
			{
				udp_->receive(20, received);  // waits for packets, takes all
			}
			catch (const std::exception& e)
			{
				core::logOnce(core::LogLevel::Error, "grab:" + decl_.section,
				              "sensor [" + decl_.section + "]: " + e.what());
			}
			const auto now = SteadyClock::now();
			for (const auto& o : received)
			{
				sink_(o, now);
				observations_++;
			}
			continue;
		}
		try
		{
			sensor.doProcess();
		}
		catch (const std::exception& e)
		{
			core::logOnce(core::LogLevel::Error, "grab:" + decl_.section,
			              "sensor [" + decl_.section + "] " + decl_.driver +
			                  ": " + e.what() + " (further errors not shown)");
		}
		CGenericSensor::TListObservations objs;
		sensor.getObservations(objs);
		const auto now = SteadyClock::now();
		for (const auto& [stamp, obj] : objs)
			if (auto obs =
			        std::dynamic_pointer_cast<mrpt::obs::CObservation>(obj))
			{
				sink_(obs, now);
				observations_++;
			}
		if (decl_.replays_file && sensor.getState() == CGenericSensor::ssError)
		{
			exhausted_ = true;  // pcap_read_once: end of the capture
			FS_LOG_INFO("sensor [" << decl_.section
			                       << "]: end of the replayed file");
			return;
		}
		std::this_thread::sleep_until(t0 + period);
	}
}

}  // namespace forest_slam::online
