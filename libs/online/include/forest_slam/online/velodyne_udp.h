#pragma once
// The UDP side of a `driver = CVelodyneScanner` sensor, received by us.
// MRPT 2.5.8's driver reads one data packet per call and then waits up to
// 1 ms on the position socket, which caps it near 1100 packets/s: a VLP-16
// sends 754/s (1508/s in dual-return mode), a replay at 5x 3770/s. This
// receiver drains both sockets in one go behind an enlarged kernel buffer and
// assembles the packets exactly like the driver (a new revolution when the
// azimuth of a packet's first block goes down; the driver's labels,
// timestamps, calibration and decimation of position packets), so the
// observations are those MRPT would have produced, with two differences:
// at stop it also delivers the revolution in progress (the driver keeps
// it), and the time base (satellite time from the position packets' fix, or
// this PC's clock) is chosen once at the first revolution and kept, where
// the driver switches when a fix comes or goes and time jumps.
#include <mrpt/obs/CObservationGPS.h>
#include <mrpt/obs/CObservationVelodyneScan.h>
#include <mrpt/obs/gnss_messages_ascii_nmea.h>
#include <mrpt/poses/CPose3D.h>

#include <string>
#include <vector>

namespace forest_slam::online
{
struct VelodyneUdpSettings
{
	std::string label;  ///< sensorLabel: observations are <label>_SCAN / _GPS
	std::string device_ip;  ///< accept packets from this sender only ("" = any)
	int data_port = 2368, position_port = 8308;
	mrpt::obs::VelodyneCalibration calibration;  ///< embedded in every scan
	double max_range_m = 120;
	mrpt::poses::CPose3D sensor_pose;
	double pos_packets_min_period_s = 0.5;
	double pos_packets_timing_timeout_s = 30;
	int receive_buffer_bytes = 16 << 20;
};

class VelodyneUdpReceiver
{
   public:
	explicit VelodyneUdpReceiver(VelodyneUdpSettings s);
	~VelodyneUdpReceiver();
	VelodyneUdpReceiver(const VelodyneUdpReceiver&) = delete;
	VelodyneUdpReceiver& operator=(const VelodyneUdpReceiver&) = delete;

	/** Binds both ports on all interfaces; throws std::runtime_error naming
	 * the port (e.g. already in use). */
	void open();
	/** Waits up to timeout_ms for packets, then takes every packet queued;
	 * appends completed revolutions and decimated GPS observations. */
	void receive(int timeout_ms,
	             std::vector<mrpt::obs::CObservation::Ptr>& out);
	/** The revolution in progress (partial), if any. */
	void flush(std::vector<mrpt::obs::CObservation::Ptr>& out);
	uint64_t packets() const { return packets_; }

   private:
	VelodyneUdpSettings s_;
	int data_fd_ = -1, pos_fd_ = -1;
	uint32_t device_addr_ = 0;  ///< network order; 0 = any
	mrpt::obs::CObservationVelodyneScan::Ptr rx_;
	mrpt::obs::gnss::Message_NMEA_RMC last_rmc_;
	mrpt::system::TTimeStamp last_rmc_time_ = INVALID_TIMESTAMP;
	mrpt::system::TTimeStamp last_pos_time_ = INVALID_TIMESTAMP;
	uint64_t packets_ = 0;
	enum class TimeBase
	{
		Undecided,
		Satellite,
		PcClock
	} time_base_ = TimeBase::Undecided;
	/** Stamps the revolution in progress and hands it over. */
	void emit(std::vector<mrpt::obs::CObservation::Ptr>& out);
	mrpt::system::TTimeStamp satelliteTime(uint32_t us_past_hour) const;
	void onData(
	    const mrpt::obs::CObservationVelodyneScan::TVelodyneRawPacket& p,
	    mrpt::system::TTimeStamp t,
	    std::vector<mrpt::obs::CObservation::Ptr>& out);
	void onPosition(
	    const mrpt::obs::CObservationVelodyneScan::TVelodynePositionPacket& p,
	    mrpt::system::TTimeStamp t,
	    std::vector<mrpt::obs::CObservation::Ptr>& out);
	/** Reads every datagram queued on fd; false if none. */
	template <typename F>
	void drain(int fd, size_t size, F&& handle);
};

}  // namespace forest_slam::online
