// Online mode's graceful degradation (doc/online.md): when scans queue up
// faster than the odometry registers them, the waiting ones get a
// constant-velocity pose and skip registration and map insertion, so the
// trajectory keeps one pose per scan and the pipeline catches up. The raw
// recording keeps every scan for a full offline re-run.
#include <forest_slam/pipeline/mapping_pipeline.h>

#include <mrpt/system/datetime.h>

#include <cmath>

namespace forest_slam::pipeline
{
bool MappingPipeline::processLightScan(const mrpt::obs::CObservation& scan)
{
	// Scans waiting for IMU samples come first: a light pose now would be
	// out of order in the trajectory. The full path queues this one too.
	if (cfg_.pipeline.poseSource() != PoseSource::Odometry ||
	    trajectory_.size() < 2 || !pending_.empty())
		return false;
	const double stamp = mrpt::Clock::toDouble(scan.timestamp);
	const auto& a = trajectory_[trajectory_.size() - 2];
	const auto& b = trajectory_.back();
	if (!std::isfinite(stamp) || stamp <= b.t_s ||
	    (have_last_scan_ && stamp <= last_scan_stamp_s_) || !(b.t_s > a.t_s))
		return false;  // the full path counts and reports it
	stats_.scans_in++;
	stats_.scans_light++;
	have_last_scan_ = true;
	last_scan_stamp_s_ = stamp;
	stats_.last_stamp_s = stamp;
	const Eigen::Isometry3d step = a.pose.inverse() * b.pose;
	trajectory_.push_back(
	    {stamp, b.pose * core::interpolateIsometry(
	                         Eigen::Isometry3d::Identity(), step,
	                         (stamp - b.t_s) / (b.t_s - a.t_s))});
	return true;
}

}  // namespace forest_slam::pipeline
