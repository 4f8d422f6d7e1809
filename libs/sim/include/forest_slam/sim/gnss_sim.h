#pragma once
// GNSS receiver: the antenna's true position (world = local ENU at the
// geodetic origin) plus an error that depends on how much sky the antenna
// sees. Sky visibility is measured by casting rays above 15 deg elevation,
// cosine-weighted towards the zenith, through the scene: solid objects block,
// each foliage volume passes 60 %.
//   visibility >= sky_open_fraction: good fix (open_fix_quality, open_sigma_m)
//   >= sky_min_fraction: fix quality 1, metre-level error that wanders
//                         (first-order Gauss-Markov, canopy_correlation_s)
//   below: no fix (quality 0).
#include <forest_slam/sim/body_trajectory.h>
#include <forest_slam/sim/options.h>
#include <forest_slam/sim/random.h>
#include <forest_slam/sim/world.h>

#include <mrpt/obs/CObservationGPS.h>

#include <vector>

namespace forest_slam::sim
{
struct GnssFix
{
	double t = 0;
	int quality = 0;  ///< NMEA GGA fix quality, 0 = no fix
	double lat_deg = 0, lon_deg = 0, height_m = 0;  ///< WGS84 ellipsoidal
	Eigen::Vector3d enu_true, enu_measured;         ///< world frame
	double sigma_h_m = 0, sigma_v_m = 0;
	double sky_fraction = 0, hdop = 0;
	int satellites = 0;
};

std::vector<GnssFix> simulateGnss(const World& world,
                                  const BodyTrajectory& body,
                                  const GnssOptions& o, Rng& rng);

/** ENU point (world frame) to WGS84 geodetic. */
void enuToGeodetic(const Eigen::Vector3d& enu, const GnssOptions& o,
                   double& lat_deg, double& lon_deg, double& h_m);

/** GGA (position, quality, HDOP, satellites) + NovAtel BESTPOS (the only
 * MRPT 2.5.8 message carrying per-axis sigmas). */
mrpt::obs::CObservationGPS::Ptr toObservation(const GnssFix& f,
                                              const GnssOptions& o);

}  // namespace forest_slam::sim
