#include <forest_slam/core/log.h>
#include <forest_slam/online/velodyne_udp.h>

#include <arpa/inet.h>
#include <mrpt/hwdrivers/CGPSInterface.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace forest_slam::online
{
using mrpt::obs::CObservationVelodyneScan;

VelodyneUdpReceiver::VelodyneUdpReceiver(VelodyneUdpSettings s)
    : s_(std::move(s))
{
	if (!s_.device_ip.empty())
	{
		in_addr a{};
		if (inet_pton(AF_INET, s_.device_ip.c_str(), &a) != 1)
			throw std::runtime_error("device_ip '" + s_.device_ip +
			                         "' is not an IPv4 address");
		device_addr_ = a.s_addr;
	}
}

VelodyneUdpReceiver::~VelodyneUdpReceiver()
{
	if (data_fd_ >= 0) ::close(data_fd_);
	if (pos_fd_ >= 0) ::close(pos_fd_);
}

void VelodyneUdpReceiver::open()
{
	for (auto [fd, port] : {std::pair<int*, int>{&data_fd_, s_.data_port},
	                        {&pos_fd_, s_.position_port}})
	{
		*fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK, 0);
		if (*fd < 0)
			throw std::runtime_error(std::string("UDP socket: ") +
			                         std::strerror(errno));
		// A deep kernel queue absorbs the moments this process does not run.
		// SO_RCVBUFFORCE (root) may exceed net.core.rmem_max; else capped.
		const int want = s_.receive_buffer_bytes;
		if (::setsockopt(*fd, SOL_SOCKET, SO_RCVBUFFORCE, &want,
		                 sizeof(want)) != 0)
			::setsockopt(*fd, SOL_SOCKET, SO_RCVBUF, &want, sizeof(want));
		sockaddr_in a{};
		a.sin_family = AF_INET;
		a.sin_addr.s_addr = htonl(INADDR_ANY);
		a.sin_port = htons(static_cast<uint16_t>(port));
		if (::bind(*fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)) != 0)
			throw std::runtime_error("cannot listen on UDP port " +
			                         std::to_string(port) + ": " +
			                         std::strerror(errno));
		int got = 0;
		socklen_t len = sizeof(got);
		::getsockopt(*fd, SOL_SOCKET, SO_RCVBUF, &got, &len);
		FS_LOG_DEBUG("UDP port " << port << ": receive buffer " << got
		                         << " bytes");
	}
}

template <typename F>
void VelodyneUdpReceiver::drain(int fd, size_t size, F&& handle)
{
	alignas(8) uint8_t buf[2048];
	for (;;)
	{
		sockaddr_in from{};
		socklen_t len = sizeof(from);
		const ssize_t n = ::recvfrom(fd, buf, sizeof(buf), MSG_DONTWAIT,
		                             reinterpret_cast<sockaddr*>(&from), &len);
		if (n < 0)
		{
			if (errno == EINTR) continue;
			return;  // EAGAIN: queue empty
		}
		if (static_cast<size_t>(n) != size ||
		    (device_addr_ && from.sin_addr.s_addr != device_addr_))
			continue;  // not a packet of our sensor (the driver skips these
			           // too)
		handle(buf, mrpt::Clock::now());
	}
}

void VelodyneUdpReceiver::receive(
    int timeout_ms, std::vector<mrpt::obs::CObservation::Ptr>& out)
{
	pollfd fds[2] = {{data_fd_, POLLIN, 0}, {pos_fd_, POLLIN, 0}};
	if (::poll(fds, 2, timeout_ms) <= 0) return;
	// Position packets first: a fix stamps the revolutions that follow it.
	drain(pos_fd_, CObservationVelodyneScan::POS_PACKET_SIZE,
	      [&](const uint8_t* b, mrpt::system::TTimeStamp t)
	      {
		      CObservationVelodyneScan::TVelodynePositionPacket p;
		      std::memcpy(&p, b, sizeof(p));
		      onPosition(p, t, out);
	      });
	drain(data_fd_, CObservationVelodyneScan::PACKET_SIZE,
	      [&](const uint8_t* b, mrpt::system::TTimeStamp t)
	      {
		      CObservationVelodyneScan::TVelodyneRawPacket p;
		      std::memcpy(&p, b, sizeof(p));
		      onData(p, t, out);
	      });
}

void VelodyneUdpReceiver::onData(
    const CObservationVelodyneScan::TVelodyneRawPacket& p,
    mrpt::system::TTimeStamp t, std::vector<mrpt::obs::CObservation::Ptr>& out)
{
	packets_++;
	if (rx_ && !rx_->scan_packets.empty() &&
	    p.blocks[0].rotation() < rx_->scan_packets.back().blocks[0].rotation())
		emit(out);  // azimuth wrapped: the revolution is complete
	if (!rx_)
	{
		rx_ = std::make_shared<CObservationVelodyneScan>();
		rx_->sensorLabel = s_.label + "_SCAN";
		rx_->sensorPose = s_.sensor_pose;
		rx_->calibration = s_.calibration;
		rx_->maxRange = s_.max_range_m;
		rx_->originalReceivedTimestamp = t;
	}
	rx_->scan_packets.push_back(p);
}

mrpt::system::TTimeStamp VelodyneUdpReceiver::satelliteTime(
    uint32_t us_past_hour) const
{
	// Date and hour from the last fix, minutes and seconds from the packet's
	// microseconds past the hour, as MRPT's driver does; but the hour is
	// the one that puts the stamp nearest to the fix, so the hour boundary
	// between a fix and the sensor's counter wrap does not jump an hour.
	const auto fix =
	    last_rmc_.fields.UTCTime.getAsTimestamp(last_rmc_.getDateAsTimestamp());
	mrpt::system::TTimeParts parts;
	mrpt::system::timestampToParts(fix, parts);
	parts.minute = static_cast<uint8_t>(us_past_hour / 60000000ul);
	parts.second = (us_past_hour % 60000000ul) * 1e-6;
	double t =
	    mrpt::Clock::toDouble(mrpt::system::buildTimestampFromParts(parts));
	const double f = mrpt::Clock::toDouble(fix);
	if (t - f > 1800) t -= 3600;
	if (f - t > 1800) t += 3600;
	return mrpt::Clock::fromDouble(t);
}

void VelodyneUdpReceiver::emit(std::vector<mrpt::obs::CObservation::Ptr>& out)
{
	if (!rx_ || rx_->scan_packets.empty()) return;
	// The time base is chosen once, at the first revolution (a fix may come
	// during it), and kept: switching later would make time jump.
	if (time_base_ == TimeBase::Undecided)
	{
		const bool fix = s_.pos_packets_timing_timeout_s > 0 &&
		                 last_rmc_.fields.validity_char == 'A' &&
		                 mrpt::system::timeDifference(
		                     last_rmc_time_, rx_->originalReceivedTimestamp) <
		                     s_.pos_packets_timing_timeout_s;
		time_base_ = fix ? TimeBase::Satellite : TimeBase::PcClock;
		FS_LOG_INFO("Velodyne '"
		            << s_.label << "': scans stamped with "
		            << (fix ? "satellite time (GPS fix in the position packets)"
		                    : "this PC's clock (no GPS fix yet, or "
		                      "pos_packets_timing_timeout = 0)")
		            << " for the whole run");
	}
	if (time_base_ == TimeBase::Satellite)
	{
		rx_->timestamp =
		    satelliteTime(rx_->scan_packets.front().gps_timestamp());
		rx_->has_satellite_timestamp = true;
	}
	else
	{
		rx_->timestamp = rx_->originalReceivedTimestamp;
		rx_->has_satellite_timestamp = false;
	}
	out.push_back(rx_);
	rx_.reset();
}

void VelodyneUdpReceiver::onPosition(
    const CObservationVelodyneScan::TVelodynePositionPacket& p,
    mrpt::system::TTimeStamp t, std::vector<mrpt::obs::CObservation::Ptr>& out)
{
	if (last_pos_time_ != INVALID_TIMESTAMP &&
	    mrpt::system::timeDifference(last_pos_time_, t) <
	        s_.pos_packets_min_period_s)
		return;  // decimated, like the driver
	last_pos_time_ = t;
	auto gps = std::make_shared<mrpt::obs::CObservationGPS>();
	gps->sensorLabel = s_.label + "_GPS";
	gps->sensorPose = s_.sensor_pose;
	gps->originalReceivedTimestamp = t;
	const std::string nmea(p.NMEA_GPRMC,
	                       strnlen(p.NMEA_GPRMC, sizeof(p.NMEA_GPRMC)));
	const bool ok = mrpt::hwdrivers::CGPSInterface::parse_NMEA(nmea, *gps);
	const auto* rmc =
	    gps->getMsgByClassPtr<mrpt::obs::gnss::Message_NMEA_RMC>();
	if (!ok || !rmc || rmc->fields.validity_char != 'A')
	{
		gps->has_satellite_timestamp = false;
		gps->timestamp = t;
	}
	else
	{
		last_rmc_time_ = t;
		last_rmc_ = *rmc;
	}
	out.push_back(gps);
}

void VelodyneUdpReceiver::flush(std::vector<mrpt::obs::CObservation::Ptr>& out)
{
	emit(out);
	rx_.reset();
}

}  // namespace forest_slam::online
