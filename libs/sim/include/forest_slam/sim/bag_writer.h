#pragma once
// The same run as a ROS1 bag, as the ROS drivers publish it:
//   /velodyne_points  sensor_msgs/PointCloud2, fields x y z intensity
//                     (float32), ring (uint16), time (float32, seconds after
//                     header.stamp); point_step 22; frame "velodyne";
//                     header.stamp = first firing; bag time = end of sweep
//   /imu/data         sensor_msgs/Imu, frame "imu_link", no orientation
//                     (orientation_covariance[0] = -1)
//   /gps/fix          sensor_msgs/NavSatFix, frame "gps"; NaN position and
//                     STATUS_NO_FIX during outages
//   /tf_static        tf2_msgs/TFMessage: base_link -> velodyne, imu_link, gps
// Written to a temporary name and renamed by close(). ROS headers stay in the
// .cpp so that users of this header do not need them.
#include <forest_slam/core/lidar_model.h>
#include <forest_slam/sim/gnss_sim.h>
#include <forest_slam/sim/imu_sim.h>
#include <forest_slam/sim/options.h>

#include <mrpt/obs/CObservationRotatingScan.h>

#include <memory>
#include <string>

namespace forest_slam::sim
{
class BagWriter
{
   public:
	/** compression: none | lz4 | bz2. Throws naming the path on failure. */
	BagWriter(const std::string& path, const std::string& compression);
	~BagWriter();
	BagWriter(const BagWriter&) = delete;
	BagWriter& operator=(const BagWriter&) = delete;

	void writeStaticTransforms(double t, const SimOptions& o);
	/** `publish_t`: bag (receive) time of the cloud. */
	void writeScan(const mrpt::obs::CObservationRotatingScan& s,
	               double publish_t);
	void writeImu(const ImuSample& s, const ImuOptions& o);
	void writeGnss(const GnssFix& f);
	void close();
	uint64_t count() const { return count_; }

   private:
	struct Impl;
	std::unique_ptr<Impl> impl_;
	std::string path_;
	bool closed_ = false;
	uint64_t count_ = 0;
};

}  // namespace forest_slam::sim
