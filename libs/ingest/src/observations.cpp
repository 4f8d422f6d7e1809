#include <forest_slam/ingest/observations.h>
#include <forest_slam/ingest/stamps.h>

#include <mrpt/math/CQuaternion.h>
#include <mrpt/obs/gnss_messages_ascii_nmea.h>
#include <mrpt/obs/gnss_messages_novatel.h>
#include <mrpt/obs/gnss_messages_topcon.h>

#include <cmath>
#include <cstring>

namespace forest_slam::ingest
{
using namespace mrpt::obs;

bool navSatCovariance(const CObservationGPS& obs, std::array<double, 9>& cov)
{
	if (!obs.hasMsgClass<gnss::Message_TOPCON_PZS>()) return false;
	const auto& p = obs.getMsgByClass<gnss::Message_TOPCON_PZS>();
	if (!p.hasPosCov) return false;
	for (int i = 0; i < 3; i++)
		for (int j = 0; j < 3; j++) cov[i * 3 + j] = p.pos_covariance(i, j);
	return true;
}

void imuFromMsg(const ImuMsg& m, CObservationIMU& out)
{
	out.timestamp = fromUnixNs(m.header.stamp_ns);
	out.dataIsPresent.fill(false);
	out.rawMeasurements.fill(0);
	// A covariance starting with -1 means "this quantity is not measured".
	if (m.linear_acceleration_covariance[0] != -1)
	{
		out.set(IMU_X_ACC, m.linear_acceleration[0]);
		out.set(IMU_Y_ACC, m.linear_acceleration[1]);
		out.set(IMU_Z_ACC, m.linear_acceleration[2]);
	}
	if (m.angular_velocity_covariance[0] != -1)
	{
		out.set(IMU_WX, m.angular_velocity[0]);
		out.set(IMU_WY, m.angular_velocity[1]);
		out.set(IMU_WZ, m.angular_velocity[2]);
	}
	const auto& q = m.orientation_xyzw;
	const double qn =
	    std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
	if (m.orientation_covariance[0] != -1 && qn > 0.5)
	{
		out.set(IMU_ORI_QUAT_X, q[0] / qn);
		out.set(IMU_ORI_QUAT_Y, q[1] / qn);
		out.set(IMU_ORI_QUAT_Z, q[2] / qn);
		out.set(IMU_ORI_QUAT_W, q[3] / qn);
		mrpt::math::CQuaternionDouble quat(q[3] / qn, q[0] / qn, q[1] / qn,
		                                   q[2] / qn);
		double yaw, pitch, roll;
		quat.rpy(roll, pitch, yaw);
		out.set(IMU_YAW, yaw);
		out.set(IMU_PITCH, pitch);
		out.set(IMU_ROLL, roll);
	}
}

uint8_t ggaQualityFromStatus(int8_t status)
{
	switch (status)
	{
		case 0:
			return 1;
		case 1:
			return 2;
		case 2:
			return 4;
		default:
			return 0;
	}
}

int8_t gpsStatusFromGga(uint8_t quality)
{
	switch (quality)
	{
		case 1:
			return 0;
		case 2:
			return 1;
		case 4:
			return 2;
		default:
			return -1;
	}
}

void gpsFromMsg(const NavSatFixMsg& m, CObservationGPS& out)
{
	out.timestamp = fromUnixNs(m.header.stamp_ns);
	out.has_satellite_timestamp = false;
	out.messages.clear();

	const int64_t sec_of_day =
	    ((m.header.stamp_ns / 1000000000LL) % 86400 + 86400) % 86400;
	const double frac = (m.header.stamp_ns % 1000000000LL) * 1e-9;
	gnss::Message_NMEA_GGA gga;
	gga.fields.UTCTime.hour = static_cast<uint8_t>(sec_of_day / 3600);
	gga.fields.UTCTime.minute = static_cast<uint8_t>((sec_of_day / 60) % 60);
	gga.fields.UTCTime.sec = static_cast<double>(sec_of_day % 60) + frac;
	gga.fields.latitude_degrees = m.latitude_deg;
	gga.fields.longitude_degrees = m.longitude_deg;
	gga.fields.fix_quality = ggaQualityFromStatus(m.status);
	// NavSatFix altitude is above the WGS84 ellipsoid; without a geoid
	// model we store it as is with zero undulation.
	gga.fields.altitude_meters = m.altitude_m;
	gga.fields.geoidal_distance = 0;
	gga.fields.orthometric_altitude = m.altitude_m;
	gga.fields.corrected_orthometric_altitude = m.altitude_m;
	gga.fields.thereis_HDOP = false;
	out.setMsg(gga);

	// BESTPOS as forest-sim writes it: solution status and 1-sigma per axis.
	const auto& c = m.position_covariance;  // ENU: x = east, y = north
	gnss::Message_NV_OEM6_BESTPOS best;
	{
		// GPS week / ms of week (18 leap seconds since 2017).
		const double gps_s = m.header.stamp_ns * 1e-9 - 315964800.0 + 18.0;
		if (gps_s > 0)
		{
			best.fields.header.week =
			    static_cast<uint16_t>(std::floor(gps_s / 604800.0));
			best.fields.header.ms_in_week = static_cast<uint32_t>(std::llround(
			    (gps_s - best.fields.header.week * 604800.0) * 1000.0));
		}
	}
	best.fields.solution_stat =
	    m.status >= 0 ? gnss::nv_oem6_solution_status::SOL_COMPUTED
	                  : gnss::nv_oem6_solution_status::INSUFFICIENT_OBS;
	best.fields.position_type =
	    m.status == 0   ? gnss::nv_oem6_position_type::SINGLE
	    : m.status == 1 ? gnss::nv_oem6_position_type::PSRDIFF
	    : m.status == 2 ? gnss::nv_oem6_position_type::NARROW_INT
	                    : gnss::nv_oem6_position_type::NONE;
	best.fields.lat = m.latitude_deg;
	best.fields.lon = m.longitude_deg;
	best.fields.hgt = m.altitude_m;
	if (m.covariance_type != 0)
	{
		best.fields.lat_sigma =
		    static_cast<float>(std::sqrt(std::max(0.0, c[4])));
		best.fields.lon_sigma =
		    static_cast<float>(std::sqrt(std::max(0.0, c[0])));
		best.fields.hgt_sigma =
		    static_cast<float>(std::sqrt(std::max(0.0, c[8])));
	}
	out.setMsg(best);

	// The covariance rides in a TOPCON PZS message: the only GNSS message
	// with a full position covariance that MRPT 2.5.8 serializes and reads
	// back (its NovAtel INSCOVS and generic frames fail to deserialize).
	// Its 4x4 matrix holds the ENU covariance in the upper-left 3x3.
	gnss::Message_TOPCON_PZS pzs;
	pzs.latitude_degrees = m.latitude_deg;
	pzs.longitude_degrees = m.longitude_deg;
	pzs.height_meters = m.altitude_m;
	pzs.RTK_height_meters = m.altitude_m;
	pzs.Fix = m.status >= 0 ? 1 : 0;
	pzs.hasPosCov = m.covariance_type != 0;
	pzs.pos_covariance.setZero();
	if (pzs.hasPosCov)
	{
		for (int i = 0; i < 3; i++)
			for (int j = 0; j < 3; j++)
				pzs.pos_covariance(i, j) = static_cast<float>(c[i * 3 + j]);
		pzs.PSigma =
		    static_cast<float>(std::sqrt(std::max(0.0, c[0] + c[4] + c[8])));
	}
	out.setMsg(pzs);
}

}  // namespace forest_slam::ingest
