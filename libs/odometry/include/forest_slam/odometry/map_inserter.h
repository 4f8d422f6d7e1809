#pragma once
// Inserts scans into the CForestMap on a worker thread, in order, while the
// odometry registers the next scan: the map's voxel filters took about a
// sixth of a scan's time and nothing in the odometry reads the CForestMap
// (registration uses its own LocalMap). Readers of the map call flush()
// first, or queue their work with run(): it then sees every scan queued
// before it, and no insertion runs at the same time.
#include <forest_slam/core/serial_worker.h>
#include <forest_slam/map/forest_map.h>

#include <Eigen/Geometry>
#include <functional>
#include <vector>

namespace forest_slam::odometry
{
class MapInserter
{
   public:
	/** max_pending: jobs waiting at most, scans and run() jobs alike (the
	 * producer blocks beyond it, so memory stays bounded when the map falls
	 * behind). 0 inserts on the caller's thread (no worker). */
	MapInserter(map::CForestMap& map, size_t max_pending);
	~MapInserter();
	MapInserter(const MapInserter&) = delete;
	MapInserter& operator=(const MapInserter&) = delete;

	/** Queues one scan: sensor-frame edge and planar points and the pose
	 * that puts them in the map (CForestMap::insertFeatures). An error of an
	 * earlier insertion is rethrown here. */
	void push(std::vector<Eigen::Vector3f> edges,
	          std::vector<Eigen::Vector3f> planar,
	          const Eigen::Isometry3d& sensor_to_map);
	/** Queues a job that reads or writes the map on the worker, after the
	 * scans queued so far (the tree layer's detections: a column's stems
	 * take hundreds of milliseconds, off the odometry's thread). */
	void run(std::function<void(map::CForestMap&)> job);
	/** Returns when every queued scan is in the map; rethrows a worker
	 * error. */
	void flush() { worker_.flush(); }

   private:
	map::CForestMap& map_;
	core::SerialWorker worker_;  ///< last: joined before the rest goes
};

}  // namespace forest_slam::odometry
