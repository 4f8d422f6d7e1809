#pragma once
// ROS 1 bags as the ROS drivers record them (velodyne_pointcloud's
// PointCloud2 layout with rings numbered bottom-up, sensor_msgs/Imu at
// 100 Hz, NavSatFix, a /tf_static chain), written with librosbag-storage.
#include <forest_slam/core/lidar_model.h>
#include <forest_slam/core/scan_points.h>

#include <mrpt/obs/CObservationRotatingScan.h>
#include <rosbag/bag.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include <cmath>
#include <cstring>
#include <string>

namespace ingest_test
{
constexpr double kT0 = 1700000000.0;
constexpr int kScans = 5, kImuPerScan = 10;

/** A small VLP-16 revolution (0.8 deg columns) as the simulator makes it. */
inline mrpt::obs::CObservationRotatingScan scanAt(int k)
{
	const int n = 450;
	mrpt::obs::CObservationRotatingScan s;
	s.rowCount = 16;
	s.columnCount = n;
	s.lidarModel = "VLP16";
	s.rangeResolution = 0.002;
	s.startAzimuth = M_PI;
	s.azimuthSpan = -2 * M_PI * (n - 1) / n;
	s.sweepDuration = 0.1 * (n - 1) / n;
	s.minRange = 0.5;
	s.maxRange = 100;
	s.timestamp = mrpt::Clock::fromDouble(kT0 + 0.1 * k);
	s.rangeImage.setZero(16, n);
	s.intensityImage.setZero(16, n);
	for (int r = 0; r < 16; r++)
		for (int c = 0; c < n; c++)
		{
			if (c > 0 && c < n - 1 && (r + c + k) % 4 == 0) continue;
			s.rangeImage(r, c) =
			    static_cast<uint16_t>(2000 + 7 * c + 100 * r + 13 * k);
			s.intensityImage(r, c) = static_cast<uint8_t>(c % 200);
		}
	return s;
}

/** velodyne_pointcloud layout; ring numbered bottom-up like the driver. */
inline sensor_msgs::PointCloud2 cloudMsg(
    const mrpt::obs::CObservationRotatingScan& s, bool drop_z = false)
{
	const auto sp = forest_slam::core::unpackRotatingScan(s);
	const auto by_el =
	    forest_slam::core::lidarModelByName("VLP16").rowsByElevation();
	std::vector<uint16_t> ring_of_row(16);
	for (int i = 0; i < 16; i++)
		ring_of_row[by_el[i]] = static_cast<uint16_t>(i);
	sensor_msgs::PointCloud2 m;
	m.header.stamp = ros::Time(sp.stamp_s);
	m.header.frame_id = "velodyne";
	const char* names[] = {"x", "y", "z", "intensity", "ring", "time"};
	const uint32_t offs[] = {0, 4, 8, 12, 16, 18};
	const uint8_t types[] = {7, 7, 7, 7, 4, 7};
	for (int i = 0; i < 6; i++)
	{
		if (drop_z && i == 2) continue;
		sensor_msgs::PointField f;
		f.name = names[i];
		f.offset = offs[i];
		f.datatype = types[i];
		f.count = 1;
		m.fields.push_back(f);
	}
	m.height = 1;
	m.width = static_cast<uint32_t>(sp.points.size());
	m.point_step = 22;
	m.row_step = 22 * m.width;
	m.is_dense = true;
	m.data.resize(m.row_step);
	uint8_t* o = m.data.data();
	for (const auto& p : sp.points)
	{
		const float v[4] = {p.x, p.y, p.z, p.intensity};
		std::memcpy(o, v, 16);
		std::memcpy(o + 16, &ring_of_row[p.ring], 2);
		std::memcpy(o + 18, &p.t_s, 4);
		o += 22;
	}
	return m;
}

inline sensor_msgs::Imu imuMsg(int i)
{
	sensor_msgs::Imu m;
	m.header.stamp = ros::Time(kT0 + 0.01 * i);
	m.header.frame_id = "imu_link";
	m.orientation_covariance[0] = -1;
	m.angular_velocity.z = 0.001 * i;
	m.linear_acceleration.z = 9.81;
	return m;
}

inline sensor_msgs::NavSatFix fixMsg(int i)
{
	sensor_msgs::NavSatFix m;
	m.header.stamp = ros::Time(kT0 + 0.25 + 0.2 * i);
	m.header.frame_id = "gps";
	m.status.status = i == 0 ? 0 : 2;
	m.latitude = 59.66 + 1e-5 * i;
	m.longitude = 10.78;
	m.altitude = 95.0;
	m.position_covariance = {0.04, 0.001, 0, 0.001, 0.05, 0, 0, 0, 0.2};
	m.position_covariance_type = sensor_msgs::NavSatFix::COVARIANCE_TYPE_KNOWN;
	return m;
}

inline geometry_msgs::TransformStamped tfMsg(const std::string& parent,
                                             const std::string& child, double x,
                                             double z, double yaw)
{
	geometry_msgs::TransformStamped t;
	t.header.stamp = ros::Time(kT0);
	t.header.frame_id = parent;
	t.child_frame_id = child;
	t.transform.translation.x = x;
	t.transform.translation.z = z;
	t.transform.rotation.z = std::sin(yaw / 2);
	t.transform.rotation.w = std::cos(yaw / 2);
	return t;
}

struct BagSpec
{
	bool tf = true;
	bool lz4 = false;
	int bad_cloud = -1;  ///< index of a cloud without its z field
	uint32_t chunk_bytes = 768 * 1024;
};

inline void writeRos1Bag(const std::string& path, const BagSpec& spec)
{
	rosbag::Bag bag(path, rosbag::bagmode::Write);
	if (spec.lz4) bag.setCompression(rosbag::compression::LZ4);
	bag.setChunkThreshold(spec.chunk_bytes);
	if (spec.tf)
	{
		tf2_msgs::TFMessage tf;
		// A chain: base_link -> mount -> velodyne.
		tf.transforms.push_back(tfMsg("base_link", "mount", 0.2, 1.0, 0));
		tf.transforms.push_back(tfMsg("mount", "velodyne", 0.1, 0.3, M_PI / 2));
		tf.transforms.push_back(tfMsg("/base_link", "imu_link", -0.05, 0.1, 0));
		tf.transforms.push_back(tfMsg("base_link", "gps", 0, 1.5, 0));
		bag.write("/tf_static", ros::Time(kT0), tf);
	}
	int imu = 0, fix = 0;
	for (int k = 0; k < kScans; k++)
	{
		for (int j = 0; j < kImuPerScan; j++, imu++)
			bag.write("/imu/data", ros::Time(kT0 + 0.01 * imu), imuMsg(imu));
		if (k % 2 == 1)
		{
			bag.write("/gps/fix", ros::Time(kT0 + 0.1 * k), fixMsg(fix));
			fix++;
		}
		// The driver publishes a revolution when it is complete.
		bag.write("/velodyne_points", ros::Time(kT0 + 0.1 * (k + 1)),
		          cloudMsg(scanAt(k), k == spec.bad_cloud));
	}
	bag.close();
}

}  // namespace ingest_test
