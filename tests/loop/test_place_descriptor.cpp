// The place descriptor on synthetic stands: the same place seen with
// another heading (and a tilted sensor) matches with that heading; other
// places of the stand do not match.
#include "synthetic_forest.h"

#include <forest_slam/loop/place_descriptor.h>
#include <gtest/gtest.h>

#include <iostream>

using namespace forest_slam::loop;
using namespace forest_slam::loop::test;

namespace
{
/** The descriptor of the view from `pose`, levelled with the pose's own
 * roll and pitch as the back-end does with the estimate's. */
PlaceDescriptor describe(const std::vector<Stem>& stems,
                         const Eigen::Isometry3d& pose, unsigned seed)
{
	auto pts = sampleView(stems, pose, 20, 0.25, seed);
	const Eigen::Matrix3f L = levellingRotation(pose.linear()).cast<float>();
	for (auto& p : pts) p = L * p;
	return PlaceDescriptor(pts, PlaceDescriptorOptions{});
}

Eigen::Isometry3d tilted(Eigen::Isometry3d T, double roll_deg, double pitch_deg)
{
	T.linear() =
	    T.linear() *
	    Eigen::AngleAxisd(roll_deg * M_PI / 180, Eigen::Vector3d::UnitX()) *
	    Eigen::AngleAxisd(pitch_deg * M_PI / 180, Eigen::Vector3d::UnitY());
	return T;
}

double wrapDeg(double a)
{
	while (a > 180) a -= 360;
	while (a < -180) a += 360;
	return a;
}
}  // namespace

TEST(PlaceDescriptor, SamePlaceMatchesWithItsYaw)
{
	const auto stems = makeStems(7, 60);
	const PlaceDescriptor a = describe(stems, poseXYZYaw(3, -2, 1.5, 0), 1);
	EXPECT_GT(a.occupancy(), 0.5);
	for (double yaw : {0.0, 37.0, 110.0, -75.0, 178.0})
	{
		// Another visit: other heading, sensor tilted, 0.3 m aside, other
		// noise.
		const PlaceDescriptor b =
		    describe(stems, tilted(poseXYZYaw(3.2, -1.8, 1.6, yaw), 4, -3), 2);
		const DescriptorMatch m = matchDescriptors(a, b);
		std::cout << "yaw " << yaw << ": distance " << m.distance
		          << ", yaw found " << m.yaw_rad * 180 / M_PI << "\n";
		EXPECT_LT(m.distance, 0.4) << "yaw " << yaw;
		EXPECT_LT(std::abs(wrapDeg(m.yaw_rad * 180 / M_PI - yaw)), 4.0)
		    << "yaw " << yaw;
	}
}

TEST(PlaceDescriptor, OtherPlacesDoNotMatch)
{
	const auto stems = makeStems(7, 60);
	const PlaceDescriptor a = describe(stems, poseXYZYaw(0, 0, 1.5, 0), 1);
	double closest = 1;
	for (double x = -30; x <= 30; x += 15)
		for (double y = -30; y <= 30; y += 15)
		{
			if (std::hypot(x, y) < 10) continue;
			const PlaceDescriptor b =
			    describe(stems, poseXYZYaw(x, y, 1.5, 20), 3);
			const DescriptorMatch m = matchDescriptors(a, b);
			closest = std::min(closest, m.distance);
			// The shipped descriptor_max_distance.
			EXPECT_GT(m.distance, 0.45) << "place " << x << ", " << y;
		}
	std::cout << "closest other place: distance " << closest << "\n";
	// Nothing seen: no match.
	const PlaceDescriptor empty({}, PlaceDescriptorOptions{});
	EXPECT_EQ(matchDescriptors(a, empty).distance, 1.0);
}
