#include <forest_slam/core/atomic_file.h>
#include <forest_slam/core/scan_points.h>
#include <forest_slam/sim/bag_writer.h>

#include <rosbag/bag.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/PointField.h>
#include <tf2_msgs/TFMessage.h>

#include <mrpt/core/Clock.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace forest_slam::sim
{
struct BagWriter::Impl
{
	rosbag::Bag bag;
	uint32_t seq_cloud = 0, seq_imu = 0, seq_fix = 0;
};

namespace
{
ros::Time rosTime(double t)
{
	return ros::Time(t);
}

geometry_msgs::TransformStamped transformOf(const Mount& m,
                                            const std::string& child, double t)
{
	const Eigen::Isometry3d T = m.toIsometry();
	const Eigen::Quaterniond q(T.linear());
	geometry_msgs::TransformStamped ts;
	ts.header.stamp = rosTime(t);
	ts.header.frame_id = "base_link";
	ts.child_frame_id = child;
	ts.transform.translation.x = T.translation().x();
	ts.transform.translation.y = T.translation().y();
	ts.transform.translation.z = T.translation().z();
	ts.transform.rotation.x = q.x();
	ts.transform.rotation.y = q.y();
	ts.transform.rotation.z = q.z();
	ts.transform.rotation.w = q.w();
	return ts;
}

sensor_msgs::PointField field(const std::string& name, uint32_t offset,
                              uint8_t type)
{
	sensor_msgs::PointField f;
	f.name = name;
	f.offset = offset;
	f.datatype = type;
	f.count = 1;
	return f;
}
}  // namespace

BagWriter::BagWriter(const std::string& path, const std::string& compression)
    : impl_(std::make_unique<Impl>()), path_(path)
{
	try
	{
		impl_->bag.open(core::tempPathFor(path), rosbag::bagmode::Write);
	}
	catch (const std::exception& e)
	{
		throw std::runtime_error("cannot create bag '" +
		                         core::tempPathFor(path) + "': " + e.what());
	}
	if (compression == "lz4")
		impl_->bag.setCompression(rosbag::compression::LZ4);
	else if (compression == "bz2")
		impl_->bag.setCompression(rosbag::compression::BZ2);
	else if (compression == "none")
		impl_->bag.setCompression(rosbag::compression::Uncompressed);
	else
		throw std::invalid_argument(
		    "bag compression must be none|lz4|bz2, got '" + compression + "'");
}

BagWriter::~BagWriter()
{
	if (!closed_)
	{
		try
		{
			impl_->bag.close();
		}
		catch (...)
		{
		}
		std::remove(core::tempPathFor(path_).c_str());
	}
}

void BagWriter::writeStaticTransforms(double t, const SimOptions& o)
{
	tf2_msgs::TFMessage msg;
	msg.transforms.push_back(transformOf(o.lidar.mount, "velodyne", t));
	msg.transforms.push_back(transformOf(o.imu.mount, "imu_link", t));
	if (o.gnss.enabled)
		msg.transforms.push_back(transformOf(o.gnss.mount, "gps", t));
	impl_->bag.write("/tf_static", rosTime(t), msg);
	count_++;
}

void BagWriter::writeScan(const mrpt::obs::CObservationRotatingScan& s,
                          double publish_t)
{
	const core::ScanPoints pts = core::unpackRotatingScan(s);
	sensor_msgs::PointCloud2 msg;
	msg.header.seq = impl_->seq_cloud++;
	msg.header.stamp = rosTime(pts.stamp_s);
	msg.header.frame_id = "velodyne";
	// velodyne_pointcloud's PointXYZIRT layout.
	msg.fields = {field("x", 0, sensor_msgs::PointField::FLOAT32),
	              field("y", 4, sensor_msgs::PointField::FLOAT32),
	              field("z", 8, sensor_msgs::PointField::FLOAT32),
	              field("intensity", 12, sensor_msgs::PointField::FLOAT32),
	              field("ring", 16, sensor_msgs::PointField::UINT16),
	              field("time", 18, sensor_msgs::PointField::FLOAT32)};
	msg.point_step = 22;
	msg.height = 1;
	msg.width = static_cast<uint32_t>(pts.points.size());
	msg.row_step = msg.point_step * msg.width;
	msg.is_bigendian = false;
	msg.is_dense = true;
	msg.data.resize(static_cast<size_t>(msg.row_step));
	uint8_t* out = msg.data.data();
	for (const auto& p : pts.points)
	{
		const float v[4] = {p.x, p.y, p.z, p.intensity};
		std::memcpy(out, v, 16);
		std::memcpy(out + 16, &p.ring, 2);
		std::memcpy(out + 18, &p.t_s, 4);
		out += 22;
	}
	impl_->bag.write("/velodyne_points", rosTime(publish_t), msg);
	count_++;
}

void BagWriter::writeImu(const ImuSample& s, const ImuOptions& o)
{
	sensor_msgs::Imu msg;
	msg.header.seq = impl_->seq_imu++;
	msg.header.stamp = rosTime(s.t);
	msg.header.frame_id = "imu_link";
	msg.orientation.w = 1;
	msg.orientation_covariance[0] = -1;  // orientation not provided
	msg.angular_velocity.x = s.gyro.x();
	msg.angular_velocity.y = s.gyro.y();
	msg.angular_velocity.z = s.gyro.z();
	msg.linear_acceleration.x = s.acc.x();
	msg.linear_acceleration.y = s.acc.y();
	msg.linear_acceleration.z = s.acc.z();
	const double vg = std::pow(o.gyro_noise_density, 2) * o.rate_hz;
	const double va = std::pow(o.accel_noise_density, 2) * o.rate_hz;
	for (int i = 0; i < 3; i++)
	{
		msg.angular_velocity_covariance[i * 4] = vg;
		msg.linear_acceleration_covariance[i * 4] = va;
	}
	impl_->bag.write("/imu/data", rosTime(s.t), msg);
	count_++;
}

void BagWriter::writeGnss(const GnssFix& f)
{
	sensor_msgs::NavSatFix msg;
	msg.header.seq = impl_->seq_fix++;
	msg.header.stamp = rosTime(f.t);
	msg.header.frame_id = "gps";
	msg.status.service = sensor_msgs::NavSatStatus::SERVICE_GPS;
	if (f.quality == 0)
	{
		const double nan = std::numeric_limits<double>::quiet_NaN();
		msg.status.status = sensor_msgs::NavSatStatus::STATUS_NO_FIX;
		msg.latitude = msg.longitude = msg.altitude = nan;
		msg.position_covariance_type =
		    sensor_msgs::NavSatFix::COVARIANCE_TYPE_UNKNOWN;
	}
	else
	{
		msg.status.status = (f.quality == 4 || f.quality == 5)
		                        ? sensor_msgs::NavSatStatus::STATUS_GBAS_FIX
		                    : f.quality == 2
		                        ? sensor_msgs::NavSatStatus::STATUS_SBAS_FIX
		                        : sensor_msgs::NavSatStatus::STATUS_FIX;
		msg.latitude = f.lat_deg;
		msg.longitude = f.lon_deg;
		msg.altitude = f.height_m;
		msg.position_covariance[0] = f.sigma_h_m * f.sigma_h_m;
		msg.position_covariance[4] = f.sigma_h_m * f.sigma_h_m;
		msg.position_covariance[8] = f.sigma_v_m * f.sigma_v_m;
		msg.position_covariance_type =
		    sensor_msgs::NavSatFix::COVARIANCE_TYPE_DIAGONAL_KNOWN;
	}
	impl_->bag.write("/gps/fix", rosTime(f.t), msg);
	count_++;
}

void BagWriter::close()
{
	if (closed_) return;
	impl_->bag.close();
	core::commitTempFile(path_);
	closed_ = true;
}

}  // namespace forest_slam::sim
