#include <forest_slam/core/progress.h>
#include <forest_slam/core/trajectory.h>
#include <gtest/gtest.h>

#include <cmath>

using namespace forest_slam::core;

TEST(Trajectory, InterpolatesTranslationAndRotation)
{
	Trajectory tr(2);
	tr[0].t_s = 10;
	tr[1].t_s = 12;
	tr[1].pose.translation() = Eigen::Vector3d(2, 4, 0);
	tr[1].pose.linear() =
		Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
	Eigen::Isometry3d p;
	ASSERT_TRUE(interpolatePose(tr, 11, p));
	EXPECT_TRUE(p.translation().isApprox(Eigen::Vector3d(1, 2, 0)));
	const Eigen::AngleAxisd aa(p.linear());
	EXPECT_NEAR(aa.angle(), M_PI / 4, 1e-9);
	EXPECT_FALSE(interpolatePose(tr, 9.0, p));
	EXPECT_FALSE(interpolatePose(tr, 12.5, p));
	EXPECT_TRUE(interpolatePose(tr, 12.0, p));
	EXPECT_TRUE(p.translation().isApprox(Eigen::Vector3d(2, 4, 0)));
}

TEST(Progress, FiguresAndEta)
{
	ProgressFigures f;
	f.scans = 200;
	f.fraction = 0.25;
	f.data_seconds = 20;
	f.wall_seconds = 2;
	EXPECT_DOUBLE_EQ(f.scansPerSecond(), 100);
	EXPECT_DOUBLE_EQ(f.realTimeFactor(), 10);
	EXPECT_DOUBLE_EQ(f.etaSeconds(), 6);
	const auto s = f.format();
	EXPECT_NE(s.find("200 scans"), std::string::npos) << s;
	EXPECT_NE(s.find("25.0%"), std::string::npos) << s;
	EXPECT_NE(s.find("10.0x real time"), std::string::npos) << s;
	EXPECT_NE(s.find("ETA 0:06"), std::string::npos) << s;
}
