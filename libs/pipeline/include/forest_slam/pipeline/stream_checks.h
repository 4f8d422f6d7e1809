#pragma once
// Plausibility checks on the sensor streams, so that a fault in field data
// (a lidar or IMU that stalls, a GNSS fix that jumps) is named in the log
// instead of silently bending the trajectory. Each check is a small state
// machine fed one stamp / fix at a time (doc/reliability.md).
#include <cstddef>
#include <cstdint>

namespace forest_slam::pipeline
{
/** Detects gaps in a stream sampled at a roughly constant rate: a gap is an
 * interval longer than `factor` times the typical interval (the smallest of
 * the recent ones) and longer than `min_gap_s`. */
class GapDetector
{
   public:
	GapDetector(double factor, double min_gap_s)
	    : factor_(factor), min_gap_s_(min_gap_s)
	{
	}
	/** Feeds the next stamp (after the previous one); returns the length of
	 * the gap it closes, or 0. */
	double observe(double t_s);
	double typicalInterval() const { return typical_s_; }

   private:
	double factor_, min_gap_s_;
	bool have_ = false;
	double last_s_ = 0, typical_s_ = 0;
	int intervals_ = 0;
};

/** Rejects GNSS fixes that moved farther from the last accepted fix than
 * the platform can travel (max_speed * dt + tolerance). After `reanchor_s`
 * of fixes that agree with each other but not with the old position, the
 * new position is accepted (a real relocation, e.g. a corrected base). */
class GnssJumpCheck
{
   public:
	GnssJumpCheck(double max_speed_mps, double tolerance_m,
	              double reanchor_s = 30.0)
	    : max_speed_(max_speed_mps),
	      tolerance_(tolerance_m),
	      reanchor_s_(reanchor_s)
	{
	}
	enum class Verdict
	{
		Accepted,
		Jump,       ///< rejected
		Reanchored  ///< accepted after a lasting jump
	};
	/** lat/lon in degrees; `distance_m` gets the horizontal distance to the
	 * reference fix. */
	Verdict observe(double t_s, double lat_deg, double lon_deg,
	                double& distance_m);

   private:
	double max_speed_, tolerance_, reanchor_s_;
	bool have_ = false;
	double t_ = 0, lat_ = 0, lon_ = 0;
	bool jumping_ = false;
	double jump_t0_ = 0, jump_lat_ = 0, jump_lon_ = 0;
	static double horizontalDistance(double lat0, double lon0, double lat1,
	                                 double lon1);
};

}  // namespace forest_slam::pipeline
