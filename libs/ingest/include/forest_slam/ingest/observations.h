#pragma once
// sensor_msgs/Imu -> CObservationIMU and sensor_msgs/NavSatFix ->
// CObservationGPS.
//
// CObservationGPS in MRPT 2.5.8 has no covariance field, so a fix is stored
// as three standard messages: NMEA GGA (position, fix quality, UTC time),
// NovAtel BESTPOS (solution status, 1-sigma east/north/up, as forest-sim
// writes it) and TOPCON PZS (position and the full ENU position covariance,
// float, in the upper-left 3x3 of its 4x4 matrix; NavSatFix's frame and units).
// PZS is the only MRPT 2.5.8 GNSS message with a covariance that survives a
// rawlog round trip (NovAtel INSCOVS and the generic frames fail to
// deserialize). navSatCovariance() reads it back. The NavSatFix status maps
// one-to-one to the GGA fix quality: -1 -> 0 (invalid), 0 -> 1 (GPS), 1 (SBAS)
// -> 2 (DGPS), 2 (GBAS) -> 4 (RTK); gpsStatusFromGga() inverts it.
#include <forest_slam/ingest/messages.h>

#include <mrpt/obs/CObservationGPS.h>
#include <mrpt/obs/CObservationIMU.h>

#include <array>

namespace forest_slam::ingest
{
/** Accelerations [m/s^2] and angular rates [rad/s] in the IMU frame, plus
 * the orientation quaternion (and yaw/pitch/roll) unless the message marks
 * it absent (orientation_covariance[0] == -1, the ROS convention). */
void imuFromMsg(const ImuMsg& m, mrpt::obs::CObservationIMU& out);

void gpsFromMsg(const NavSatFixMsg& m, mrpt::obs::CObservationGPS& out);

/** The ENU position covariance [m^2, row-major, float precision] stored by
 * gpsFromMsg(); false if the fix had none. */
bool navSatCovariance(const mrpt::obs::CObservationGPS& obs,
                      std::array<double, 9>& cov);

uint8_t ggaQualityFromStatus(int8_t status);
int8_t gpsStatusFromGga(uint8_t quality);

}  // namespace forest_slam::ingest
