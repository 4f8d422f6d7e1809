// The tree layer's hook into the mapping pipeline: points of every mapped
// scan, in the map frame, go to trees::TreeLayer, which detects the stems of
// the submap columns the sensor has left and updates the CForestMap tree
// layer (doc/trees.md "Tree layer of a SLAM run").
#include <forest_slam/pipeline/mapping_pipeline.h>

#include <chrono>

namespace forest_slam::pipeline
{
namespace
{
double msSince(std::chrono::steady_clock::time_point t0)
{
	return std::chrono::duration<double, std::milli>(
	           std::chrono::steady_clock::now() - t0)
	    .count();
}
}  // namespace

void MappingPipeline::feedTreeLayer(const std::vector<Eigen::Vector3f>& a,
                                    const std::vector<Eigen::Vector3f>& b,
                                    const Eigen::Vector3d& sensor)
{
	if (!tree_layer_) return;
	const auto t0 = std::chrono::steady_clock::now();
	std::vector<Eigen::Vector3f> pts;
	pts.reserve(a.size() + b.size());
	pts.insert(pts.end(), a.begin(), a.end());
	pts.insert(pts.end(), b.begin(), b.end());
	tree_layer_->addScan(pts, sensor);
	tree_layer_->update(sensor, map_);
	stats_.tree_ms.push_back(msSince(t0));
}

void MappingPipeline::feedTreeLayerOdometry(core::ScanPoints&& scan)
{
	if (!tree_layer_) return;
	// The odometry gives the pose at the scan's first firing; a scan's
	// points are deskewed between its pose and the next scan's.
	if (tree_pending_) flushPendingTreeScan();
	tree_pending_ = std::move(scan);
}

void MappingPipeline::flushPendingTreeScan()
{
	if (!tree_pending_ || trajectory_.empty()) return;
	const auto t0 = std::chrono::steady_clock::now();
	const core::ScanPoints& s = *tree_pending_;
	Eigen::Isometry3d T0;
	if (!core::interpolatePose(trajectory_, s.stamp_s, T0, 1e-6))
		T0 = trajectory_.back().pose;
	std::vector<Eigen::Vector3f> pts;
	pts.reserve(s.points.size());
	// One pose per firing column (at most a few thousand interpolations).
	uint16_t last_col = 0;
	Eigen::Isometry3f T = T0.cast<float>();
	bool have = false;
	for (const auto& p : s.points)
	{
		if (!have || p.column != last_col)
		{
			Eigen::Isometry3d Tp;
			T = core::interpolatePose(trajectory_, s.stamp_s + p.t_s, Tp, 1e-6)
			        ? Tp.cast<float>()
			        : trajectory_.back().pose.cast<float>();
			last_col = p.column;
			have = true;
		}
		pts.push_back(T * Eigen::Vector3f(p.x, p.y, p.z));
	}
	const Eigen::Vector3d sensor = T0.translation();
	tree_pending_.reset();
	tree_layer_->addScan(pts, sensor);
	tree_layer_->update(sensor, map_);
	stats_.tree_ms.push_back(msSince(t0));
}

void MappingPipeline::finishTreeLayer()
{
	if (!tree_layer_) return;
	flushPendingTreeScan();
	const auto t0 = std::chrono::steady_clock::now();
	tree_layer_->finish(map_);
	stats_.tree_finish_ms = msSince(t0);
}

}  // namespace forest_slam::pipeline
