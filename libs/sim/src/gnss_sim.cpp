#include <forest_slam/sim/gnss_sim.h>

#include <mrpt/core/Clock.h>
#include <mrpt/obs/gnss_messages_ascii_nmea.h>
#include <mrpt/obs/gnss_messages_novatel.h>
#include <GeographicLib/LocalCartesian.hpp>

#include <algorithm>
#include <cmath>

namespace forest_slam::sim
{
namespace
{
/** Fraction of signal reaching the antenna over directions above 15 deg,
 * cosine-weighted towards the zenith (z = sin(elevation) spaced so that the
 * density is proportional to z): low satellites are weak and masked anyway,
 * and it is the sky overhead that tells a clearing from a closed canopy. */
double skyVisibility(const World& world, const Eigen::Vector3d& p, int n_rays,
                     uint64_t key, RayScratch& scratch)
{
	const double z_min = std::sin(15 * M_PI / 180);
	const double golden = M_PI * (3 - std::sqrt(5.0));
	double sum = 0;
	for (int i = 0; i < n_rays; i++)
	{
		const double z =
		    std::sqrt(z_min * z_min + (1 - z_min * z_min) * (i + 0.5) / n_rays);
		const double r = std::sqrt(1 - z * z), az = i * golden;
		const Eigen::Vector3d d(r * std::cos(az), r * std::sin(az), z);
		double trans = 1, t0 = 0.05;
		for (int hop = 0; hop < 8 && trans > 0; hop++)
		{
			const Hit h = world.raycast(
			    p, d, t0, 300.0, hashCombine(key, i * 16 + hop), scratch);
			if (!h.valid()) break;
			if (!h.porous)
			{
				trans = 0;
				break;
			}
			trans *= 0.6;
			// Skip past this foliage volume's leaf and keep going up.
			t0 = h.t + 0.5;
		}
		sum += trans;
	}
	return sum / n_rays;
}

/** GPS week and milliseconds of week from UNIX time (18 leap seconds). */
void gpsTime(double unix_s, uint16_t& week, uint32_t& ms)
{
	const double gps = unix_s - 315964800.0 + 18.0;
	week = static_cast<uint16_t>(std::floor(gps / 604800.0));
	ms = static_cast<uint32_t>(std::llround((gps - week * 604800.0) * 1000.0));
}
}  // namespace

void enuToGeodetic(const Eigen::Vector3d& enu, const GnssOptions& o,
                   double& lat_deg, double& lon_deg, double& h_m)
{
	// GeographicLib, not mrpt::topography::ENUToGeocentric: in MRPT 2.5.8
	// that one is off by ~0.15 % of the distance (1.5 m at 1 km), while
	// MRPT's geodeticToENU_WGS84 (what consumers use) agrees with this to
	// 1e-8 m.
	const GeographicLib::LocalCartesian lc(o.origin_lat_deg, o.origin_lon_deg,
	                                       o.origin_height_m);
	lc.Reverse(enu.x(), enu.y(), enu.z(), lat_deg, lon_deg, h_m);
}

std::vector<GnssFix> simulateGnss(const World& world,
                                  const BodyTrajectory& body,
                                  const GnssOptions& o, Rng& rng)
{
	std::vector<GnssFix> out;
	if (!o.enabled) return out;
	const Eigen::Vector3d ant = o.mount.toIsometry().translation();
	const double dt = 1.0 / o.rate_hz;
	const double phi = std::exp(-dt / o.canopy_correlation_s);
	const double q = std::sqrt(1 - phi * phi);
	Eigen::Vector3d gm(rng.normal(), rng.normal(),
	                   rng.normal());  // unit variance
	const uint64_t key = rng.next();
	RayScratch scratch;
	const double t0 = body.startTime(), t1 = body.endTime();
	const long n =
	    static_cast<long>(std::floor((t1 - t0) * o.rate_hz + 1e-9)) + 1;
	for (long i = 0; i < n; i++)
	{
		GnssFix f;
		f.t = t0 + i * dt;
		f.enu_true = body.pose(f.t) * ant;
		f.sky_fraction = skyVisibility(world, f.enu_true, o.sky_rays,
		                               hashCombine(key, i), scratch);
		const Eigen::Vector3d white(rng.normal(), rng.normal(), rng.normal());
		gm = phi * gm +
		     q * Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal());
		if (f.sky_fraction >= o.sky_open_fraction)
		{
			f.quality = o.open_fix_quality;
			f.sigma_h_m = o.open_sigma_m;
			f.hdop = 0.6 + 0.4 * (1 - f.sky_fraction);
			f.enu_measured =
			    f.enu_true +
			    Eigen::Vector3d(white.x() * f.sigma_h_m,
			                    white.y() * f.sigma_h_m,
			                    white.z() * f.sigma_h_m * o.vertical_factor);
		}
		else if (f.sky_fraction >= o.sky_min_fraction)
		{
			// Worse the less sky: from canopy_sigma_m up to twice that.
			const double x = (o.sky_open_fraction - f.sky_fraction) /
			                 (o.sky_open_fraction - o.sky_min_fraction);
			f.quality = 1;
			f.sigma_h_m = o.canopy_sigma_m * (1 + x);
			f.hdop = 1.0 + 3.0 * x;
			f.enu_measured =
			    f.enu_true +
			    Eigen::Vector3d(gm.x() * f.sigma_h_m, gm.y() * f.sigma_h_m,
			                    gm.z() * f.sigma_h_m * o.vertical_factor);
		}
		else
		{
			f.quality = 0;
			f.enu_measured = f.enu_true;
		}
		f.sigma_v_m = f.sigma_h_m * o.vertical_factor;
		f.satellites =
		    f.quality > 0
		        ? static_cast<int>(std::lround(5 + 14 * f.sky_fraction))
		        : 0;
		if (f.quality > 0)
			enuToGeodetic(f.enu_measured, o, f.lat_deg, f.lon_deg, f.height_m);
		out.push_back(f);
	}
	return out;
}

mrpt::obs::CObservationGPS::Ptr toObservation(const GnssFix& f,
                                              const GnssOptions& o)
{
	using namespace mrpt::obs::gnss;
	auto obs = mrpt::obs::CObservationGPS::Create();
	obs->sensorLabel = "gnss";
	obs->timestamp = mrpt::Clock::fromDouble(f.t);
	obs->originalReceivedTimestamp = mrpt::Clock::fromDouble(f.t + 0.05);
	obs->has_satellite_timestamp = true;
	obs->sensorPose = o.mount.toCPose3D();

	Message_NMEA_GGA gga;
	const double day_s = std::fmod(f.t, 86400.0);
	gga.fields.UTCTime.hour = static_cast<uint8_t>(day_s / 3600);
	gga.fields.UTCTime.minute =
	    static_cast<uint8_t>(std::fmod(day_s, 3600.0) / 60);
	gga.fields.UTCTime.sec = std::fmod(day_s, 60.0);
	gga.fields.fix_quality = static_cast<uint8_t>(f.quality);
	gga.fields.latitude_degrees = f.lat_deg;
	gga.fields.longitude_degrees = f.lon_deg;
	// Heights are ellipsoidal; the geoid undulation is taken as zero.
	gga.fields.altitude_meters = f.height_m;
	gga.fields.geoidal_distance = 0;
	gga.fields.orthometric_altitude = f.height_m;
	gga.fields.corrected_orthometric_altitude = f.height_m;
	gga.fields.satellitesUsed = static_cast<uint32_t>(f.satellites);
	gga.fields.thereis_HDOP = f.quality > 0;
	gga.fields.HDOP = static_cast<float>(f.hdop);
	obs->setMsg(gga);

	Message_NV_OEM6_BESTPOS best;
	gpsTime(f.t, best.fields.header.week, best.fields.header.ms_in_week);
	best.fields.solution_stat = f.quality > 0
	                                ? nv_oem6_solution_status::SOL_COMPUTED
	                                : nv_oem6_solution_status::INSUFFICIENT_OBS;
	best.fields.position_type =
	    f.quality == 0   ? nv_oem6_position_type::NONE
	    : f.quality == 4 ? nv_oem6_position_type::NARROW_INT
	    : f.quality == 5 ? nv_oem6_position_type::NARROW_FLOAT
	    : f.quality == 2 ? nv_oem6_position_type::PSRDIFF
	                     : nv_oem6_position_type::SINGLE;
	best.fields.lat = f.lat_deg;
	best.fields.lon = f.lon_deg;
	best.fields.hgt = f.height_m;
	best.fields.lat_sigma = static_cast<float>(f.sigma_h_m);
	best.fields.lon_sigma = static_cast<float>(f.sigma_h_m);
	best.fields.hgt_sigma = static_cast<float>(f.sigma_v_m);
	best.fields.num_sats_tracked = static_cast<uint8_t>(f.satellites);
	best.fields.num_sats_sol = static_cast<uint8_t>(f.satellites);
	obs->setMsg(best);
	return obs;
}

}  // namespace forest_slam::sim
