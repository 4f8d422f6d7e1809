// Online mode's degradation when the pipeline falls behind: light scans get
// the constant-velocity pose, leave the map alone, and the odometry picks up
// again afterwards.
#include "synthetic_scans.h"

#include <forest_slam/pipeline/mapping_pipeline.h>
#include <gtest/gtest.h>

using namespace forest_slam;

namespace
{
pipeline::MappingPipeline makePipeline(const std::string& pose_source)
{
	auto cfg = core::TrackedConfig::fromText(
	    "[pipeline]\npose_source = " + pose_source + "\n", "light.ini");
	return pipeline::MappingPipeline(pipeline::MappingConfig::load(cfg));
}
}  // namespace

TEST(LightScans, MotionModelPoseNoMapChangeThenOdometryResumes)
{
	auto p = makePipeline("odometry");
	test_support::MovingSensorWorld w;
	auto feed = [&](int k)
	{
		p.process(
		    std::make_shared<mrpt::obs::CObservationRotatingScan>(w.scan(k)));
	};
	for (int k = 0; k < 6; k++) feed(k);
	const auto edges = p.forestMap().edgePointCount();
	const auto planar = p.forestMap().planarPointCount();
	p.setLightScans(true);
	for (int k = 6; k < 9; k++) feed(k);
	EXPECT_EQ(p.forestMap().edgePointCount(), edges);
	EXPECT_EQ(p.forestMap().planarPointCount(), planar);
	p.setLightScans(false);
	for (int k = 9; k < 15; k++) feed(k);

	ASSERT_EQ(p.trajectory().size(), 15u);  // one pose per scan
	EXPECT_EQ(p.stats().scans_light, 3u);
	EXPECT_EQ(p.stats().scans_mapped, 12u);
	EXPECT_EQ(p.stats().scans_in, 15u);
	for (int k = 0; k < 15; k++)
	{
		const Eigen::Vector3d truth = w.positionAt(w.t0_s + k * w.period_s);
		// Constant velocity: the extrapolated poses are as good as tracked
		// ones, and tracking continues after the gap in the map updates.
		EXPECT_LT((p.trajectory()[k].pose.translation() - truth).norm(), 0.1)
		    << "scan " << k;
		if (k > 0)
		{
			EXPECT_GT(p.trajectory()[k].t_s, p.trajectory()[k - 1].t_s);
		}
	}
}

TEST(LightScans, NeedTwoPosesAndOnlyConcernOdometry)
{
	test_support::MovingSensorWorld w;
	auto odo = makePipeline("odometry");
	odo.setLightScans(true);  // no two poses yet: processed fully
	odo.process(
	    std::make_shared<mrpt::obs::CObservationRotatingScan>(w.scan(0)));
	odo.process(
	    std::make_shared<mrpt::obs::CObservationRotatingScan>(w.scan(1)));
	EXPECT_EQ(odo.stats().scans_light, 0u);
	EXPECT_EQ(odo.stats().scans_mapped, 2u);
	odo.process(
	    std::make_shared<mrpt::obs::CObservationRotatingScan>(w.scan(2)));
	EXPECT_EQ(odo.stats().scans_light, 1u);
	// Out of order stays out of order (counted by the full path).
	odo.process(
	    std::make_shared<mrpt::obs::CObservationRotatingScan>(w.scan(1)));
	EXPECT_EQ(odo.stats().scans_light, 1u);
	EXPECT_EQ(odo.stats().scans_out_of_order, 1u);

	auto fixed = makePipeline("static");
	fixed.setLightScans(true);
	for (int k = 0; k < 3; k++)
		fixed.process(
		    std::make_shared<mrpt::obs::CObservationRotatingScan>(w.scan(k)));
	EXPECT_EQ(fixed.stats().scans_light, 0u);
	EXPECT_EQ(fixed.stats().scans_mapped, 3u);
}
