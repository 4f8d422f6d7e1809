#include <forest_slam/sim/lidar_sim.h>
#include <forest_slam/sim/random.h>

#include <mrpt/core/Clock.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <thread>

namespace forest_slam::sim
{
namespace
{
uint32_t noiseMask(const LidarOptions& o)
{
	if (const auto m = o.rangeNoiseMask()) return *m;
	throw std::invalid_argument(
	    "[lidar] range_noise_classes = '" + o.range_noise_classes +
	    "': expected all, or a list of ground, stem, crown, shrub, structure");
}
}  // namespace

LidarSimulator::LidarSimulator(const World& world, const BodyTrajectory& body,
                               const LidarOptions& o, uint64_t seed,
                               int threads)
    : world_(world),
      body_(body),
      o_(o),
      model_(core::lidarModelByName(o.model)),
      seed_(seed),
      noise_mask_(noiseMask(o)),
      threads_(std::max(1, threads)),
      body_to_lidar_(o.mount.toIsometry())
{
	period_ = 1.0 / o.rate_hz;
	// The azimuth step grows with the spin rate (fixed firing rate).
	const double step =
	    o.azimuth_step_deg > 0
	        ? o.azimuth_step_deg * M_PI / 180.0
	        : model_.azimuth_step_rad * o.rate_hz / model_.default_rate_hz;
	n_cols_ = std::max(2, static_cast<int>(std::lround(2 * M_PI / step)));
	if (n_cols_ > 65535) n_cols_ = 65535;
	sweep_ = period_ * (n_cols_ - 1) / n_cols_;
	// Velodynes spin clockwise seen from above (decreasing azimuth).
	const double span = 2 * M_PI * (n_cols_ - 1) / n_cols_;
	start_az_ = o.clockwise ? M_PI : -M_PI;
	span_ = o.clockwise ? -span : span;
	min_range_ = o.min_range_m > 0 ? o.min_range_m : model_.min_range_m;
	max_range_ = o.max_range_m > 0 ? o.max_range_m : model_.max_range_m;
	t0_ = body.startTime();
	const double usable = body.endTime() - t0_ - sweep_;
	n_scans_ =
	    usable >= 0
	        ? static_cast<size_t>(std::floor(usable / period_ + 1e-9)) + 1
	        : 0;
	for (double e : model_.elevation_rad)
	{
		cos_el_.push_back(std::cos(e));
		sin_el_.push_back(std::sin(e));
	}
	scratch_.resize(threads_);
}

mrpt::obs::CObservationRotatingScan::Ptr LidarSimulator::scan(size_t k)
{
	const int rows = static_cast<int>(model_.rings()), cols = n_cols_;
	auto obs = mrpt::obs::CObservationRotatingScan::Create();
	obs->sensorLabel = "lidar";
	obs->lidarModel = model_.name;
	obs->rowCount = static_cast<uint16_t>(rows);
	obs->columnCount = static_cast<uint16_t>(cols);
	obs->rangeImage.setZero(rows, cols);
	obs->intensityImage.setZero(rows, cols);
	obs->rangeResolution = o_.range_resolution_m;
	obs->startAzimuth = start_az_;
	obs->azimuthSpan = span_;
	obs->sweepDuration = sweep_;
	obs->minRange = min_range_;
	obs->maxRange = max_range_;
	obs->sensorPose = o_.mount.toCPose3D();
	const double t_scan = scanTime(k);
	obs->timestamp = mrpt::Clock::fromDouble(t_scan);
	// A driver publishes the revolution once it is complete.
	obs->originalReceivedTimestamp = mrpt::Clock::fromDouble(t_scan + period_);
	mrpt::math::CMatrix_u16* label_img = nullptr;
	mrpt::math::CMatrix_u16* tree_img = nullptr;
	if (o_.gt_layers)
	{
		label_img = &obs->rangeOtherLayers["gt_label"];
		tree_img = &obs->rangeOtherLayers["gt_tree"];
		label_img->setZero(rows, cols);
		tree_img->setZero(rows, cols);
	}
	const uint64_t scan_key = hashCombine(seed_, k);
	const double res = o_.range_resolution_m;

	auto work = [&](int th)
	{
		RayScratch& scratch = scratch_[th];
		const int c0 = cols * th / threads_, c1 = cols * (th + 1) / threads_;
		for (int c = c0; c < c1; c++)
		{
			const double dt_c = sweep_ * c / (cols - 1);
			const Eigen::Isometry3d T =
			    body_.pose(t_scan + dt_c) * body_to_lidar_;
			const Eigen::Vector3d o = T.translation();
			const double az = start_az_ + span_ * c / (cols - 1);
			const double ca = std::cos(az), sa = std::sin(az);
			for (int r = 0; r < rows; r++)
			{
				const Eigen::Vector3d d_s(cos_el_[r] * ca, cos_el_[r] * sa,
				                          sin_el_[r]);
				const Eigen::Vector3d d = T.linear() * d_s;
				const uint64_t key =
				    hashCombine(scan_key, static_cast<uint64_t>(c) * 1024 + r);
				const Hit hit =
				    world_.raycast(o, d, 0.0, max_range_, key, scratch);
				if (!hit.valid()) continue;
				// Returned power ~ reflectivity x incidence / r^2: darker and
				// grazing targets vanish earlier than max range.
				const double power =
				    hit.reflectivity * (0.3 + 0.7 * hit.cos_incidence) / 100.0;
				if (hit.t > max_range_ * std::sqrt(std::max(power, 0.0)))
					continue;
				if (o_.dropout_probability > 0 &&
				    hashUniform(key ^ 0x1111) < o_.dropout_probability)
					continue;
				const double noise =
				    (noise_mask_ >> hit.label) & 1u
				        ? o_.range_noise_m * hashNormal(key ^ 0x2222)
				        : 0.0;
				const double range = hit.t + noise;
				if (range < min_range_ || range > max_range_) continue;
				const long raw = std::lround(range / res);
				if (raw <= 0 || raw > 65535) continue;
				double inten =
				    hit.reflectivity * (0.4 + 0.6 * hit.cos_incidence);
				if (range < 2.0)
					inten *= 0.5 + 0.25 * range;  // near-field optics
				inten += o_.intensity_noise * hashNormal(key ^ 0x3333);
				obs->rangeImage(r, c) = static_cast<uint16_t>(raw);
				obs->intensityImage(r, c) = static_cast<uint8_t>(
				    std::clamp(std::lround(inten), 0L, 255L));
				if (label_img)
				{
					(*label_img)(r, c) = hit.label;
					(*tree_img)(r, c) = hit.tree;
				}
			}
		}
	};
	if (threads_ == 1)
		work(0);
	else
	{
		std::vector<std::thread> pool;
		for (int th = 1; th < threads_; th++) pool.emplace_back(work, th);
		work(0);
		for (auto& t : pool) t.join();
	}
	return obs;
}

}  // namespace forest_slam::sim
