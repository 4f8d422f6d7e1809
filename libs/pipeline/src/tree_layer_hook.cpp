// The tree layer's hook into the mapping pipeline: points of every mapped
// scan, in the map frame, go to trees::TreeLayer, which detects the stems of
// the submap columns the sensor has left and updates the CForestMap tree
// layer (doc/trees.md "Tree layer of a SLAM run").
#include <forest_slam/core/log.h>
#include <forest_slam/core/memory.h>
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
	tree_layer_->addScan(pts, sensor, trajectory_.back().t_s);
	tree_layer_->update(sensor, map_);
	stats_.tree_ms.push_back(msSince(t0));
}

void MappingPipeline::feedTreeLayerOdometry(const Eigen::Isometry3d& scan_pose)
{
	if (!tree_layer_) return;
	// The odometry's own deskew (IMU rotation and accelerometer translation
	// per firing column), placed with the scan's pose. Interpolating between
	// consecutive scan poses instead missed the sway of a handheld rig
	// within the sweep: stems 15 m away blurred by several cm (issue 7).
	// The layer runs on the CForestMap's thread, after this scan's
	// insertion: a column's detection reads the map's voxels (tree tops) and
	// takes hundreds of milliseconds, which held the odometry up (the layer
	// was 40-48 % of the handheld and robot runs' wall time on this thread).
	odometry_->runOnMap(
	    [this, local = odometry_->lastDeskewed(), T = scan_pose.cast<float>(),
	     sensor = Eigen::Vector3d(scan_pose.translation()),
	     t_s = trajectory_.back().t_s](map::CForestMap& map)
	    {
		    const auto t0 = std::chrono::steady_clock::now();
		    std::vector<Eigen::Vector3f> pts(local.size());
		    for (size_t i = 0; i < local.size(); i++) pts[i] = T * local[i];
		    tree_layer_->addScan(pts, sensor, t_s);
		    tree_layer_->update(sensor, map);
		    stats_.tree_ms.push_back(msSince(t0));
	    });
}

void MappingPipeline::finishTreeLayer()
{
	if (!tree_layer_) return;
	const auto t0 = std::chrono::steady_clock::now();
	tree_layer_->finish(map_);
	// Every column is detected and the back-end's final correction is done
	// (finishBackEnd runs first): the stem-band voxels are not read again.
	tree_layer_->releaseStemVoxels();
	core::releaseFreedHeap();  // what the map thread freed
	stats_.tree_finish_ms = msSince(t0);
	FS_LOG_INFO("tree layer: end-of-run detection in "
	            << 1e-3 * stats_.tree_finish_ms << " s; peak RSS so far "
	            << core::peakRssMb() << " MB");
}

}  // namespace forest_slam::pipeline
