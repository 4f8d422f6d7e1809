#pragma once
// [faults]: sensor faults injected into the generated streams, so that tests
// can check the mapping pipeline copes with field-data mishaps (a lidar that
// drops packets, an IMU that stalls, GNSS that jumps; doc/reliability.md).
// Kept apart from the scenario options: a fault changes the recorded data,
// never the world, the motion or the ground truth.
#include <forest_slam/core/config.h>

#include <mrpt/config/CLoadableOptions.h>

#include <string>
#include <vector>

namespace mrpt::obs
{
class CObservationRotatingScan;
}

namespace forest_slam::sim
{
struct ImuSample;
struct GnssFix;
struct GnssOptions;

/** Every time is in seconds after the first lidar firing; a negative time
 * leaves that fault out (the default: no fault). */
struct FaultOptions : public mrpt::config::CLoadableOptions
{
	/** The first scan at or after this time has non-finite geometry (azimuth
	 * span NaN): every point it decodes to is NaN. */
	double nan_scan_at_s = -1;
	/** The first scan at or after this time has no return at all. */
	double empty_scan_at_s = -1;
	/** No lidar scan during [lidar_gap_at_s, + lidar_gap_s). */
	double lidar_gap_at_s = -1;
	double lidar_gap_s = 2.0;
	/** No IMU sample during [imu_gap_at_s, + imu_gap_s). */
	double imu_gap_at_s = -1;
	double imu_gap_s = 1.0;
	/** The first IMU sample at or after this time is stamped
	 * imu_backwards_s before the sample preceding it. */
	double imu_backwards_at_s = -1;
	double imu_backwards_s = 0.05;
	/** GNSS fixes during [gnss_jump_at_s, + gnss_jump_duration_s) are moved
	 * gnss_jump_m east (a wrong fix, not a true motion). */
	double gnss_jump_at_s = -1;
	double gnss_jump_m = 50.0;
	double gnss_jump_duration_s = 5.0;
	/** The first scan at or after this time is written twice. */
	double duplicate_scan_at_s = -1;
	/** Scans during [open_field_at_s, + open_field_s) keep only their ground
	 * returns (gt_label 1): the sensor sees what it would in an open field,
	 * a degenerate place for the registration. Needs [lidar] gt_layers. */
	double open_field_at_s = -1;
	double open_field_s = 3.0;

	bool any() const;
	/** Throws core::ConfigError naming [faults] and the key. */
	void validate(const std::string& origin) const;
	/** One line per active fault, for the log. */
	std::vector<std::string> describe() const;
	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

/** What happens to one lidar scan. */
enum class ScanFault
{
	None,
	Drop,       ///< inside the lidar gap: not written
	NonFinite,  ///< written with NaN geometry
	Empty,      ///< written without returns
	Duplicate,  ///< written twice
	OpenField   ///< ground returns only
};

/** The fault of the scan at t_rel_s (seconds after the first firing), for
 * scans every period_s. */
ScanFault scanFault(const FaultOptions& f, double t_rel_s, double period_s);

/** Applies NonFinite / Empty / OpenField to a scan (the others are the
 * writer's). OpenField throws std::invalid_argument without gt_label. */
void applyScanFault(ScanFault fault, mrpt::obs::CObservationRotatingScan& s);

/** IMU gap and backwards stamp, on the samples (t0_s = first firing). */
void applyImuFaults(const FaultOptions& f, double t0_s,
                    std::vector<ImuSample>& imu);

/** GNSS jump on the fixes (measured ENU and geodetic position). */
void applyGnssFaults(const FaultOptions& f, double t0_s, const GnssOptions& o,
                     std::vector<GnssFix>& gnss);

}  // namespace forest_slam::sim
