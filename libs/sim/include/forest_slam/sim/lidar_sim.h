#pragma once
// Spinning lidar: one CObservationRotatingScan per revolution. Every column
// (firing) is cast from the lidar pose at its own instant, so a moving
// sensor produces real motion distortion. Column c has azimuth
// startAzimuth + azimuthSpan*c/(n-1) and time sweepDuration*c/(n-1) after
// the scan timestamp, the convention of core/scan_points.h. Row r is laser
// id r of core::lidarModelByName(model).
#include <forest_slam/core/lidar_model.h>
#include <forest_slam/sim/body_trajectory.h>
#include <forest_slam/sim/options.h>
#include <forest_slam/sim/world.h>

#include <mrpt/obs/CObservationRotatingScan.h>

#include <cstdint>

namespace forest_slam::sim
{
class LidarSimulator
{
   public:
	/** Scans cover [body.startTime(), body.endTime()]; `seed` feeds the
	 * per-ray noise hashes. */
	LidarSimulator(const World& world, const BodyTrajectory& body,
	               const LidarOptions& o, uint64_t seed, int threads);

	size_t scanCount() const { return n_scans_; }
	/** First firing of scan k (UNIX seconds). */
	double scanTime(size_t k) const { return t0_ + k * period_; }
	int columns() const { return n_cols_; }
	double sweepDuration() const { return sweep_; }
	double startAzimuth() const { return start_az_; }
	double azimuthSpan() const { return span_; }
	double minRange() const { return min_range_; }
	double maxRange() const { return max_range_; }
	const core::LidarModel& model() const { return model_; }

	/** Casts scan k; thread-safe for distinct calls only if `threads`=1.
	 * Deterministic: independent of the thread count. */
	mrpt::obs::CObservationRotatingScan::Ptr scan(size_t k);

   private:
	const World& world_;
	const BodyTrajectory& body_;
	LidarOptions o_;
	const core::LidarModel& model_;
	uint64_t seed_;
	uint32_t noise_mask_;  ///< LidarOptions::rangeNoiseMask()
	int threads_;
	Eigen::Isometry3d body_to_lidar_;  ///< lidar -> body
	double t0_, period_, sweep_, start_az_, span_;
	double min_range_, max_range_;
	int n_cols_ = 0;
	size_t n_scans_ = 0;
	std::vector<double> cos_el_, sin_el_;
	std::vector<RayScratch> scratch_;
};

}  // namespace forest_slam::sim
