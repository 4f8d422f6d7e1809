#include <forest_slam/eval/trajectory_metrics.h>
#include <gtest/gtest.h>

#include <cmath>

using namespace forest_slam;
using namespace forest_slam::eval;

namespace
{
constexpr double kDeg = M_PI / 180.0;

core::StampedPose pose(double t, double x, double y, double z,
                       double yaw_deg = 0, double pitch_deg = 0,
                       double roll_deg = 0)
{
	core::StampedPose p;
	p.t_s = t;
	p.pose.linear() =
	    (Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitZ()) *
	     Eigen::AngleAxisd(pitch_deg * kDeg, Eigen::Vector3d::UnitY()) *
	     Eigen::AngleAxisd(roll_deg * kDeg, Eigen::Vector3d::UnitX()))
	        .toRotationMatrix();
	p.pose.translation() = Eigen::Vector3d(x, y, z);
	return p;
}

/** 10 m square, one pose per metre (40 poses, t = index), heading along
 * the side being walked. */
core::Trajectory square()
{
	core::Trajectory t;
	for (int i = 0; i < 40; i++)
	{
		const int side = i / 10, k = i % 10;
		const double xy[4][2] = {
		    {double(k), 0}, {10, double(k)}, {10.0 - k, 10}, {0, 10.0 - k}};
		t.push_back(pose(i, xy[side][0], xy[side][1], 0, 90.0 * side));
	}
	return t;
}

PosePairs pairsOf(const core::Trajectory& gt, const core::Trajectory& est)
{
	return associateByInterpolation(gt, est).pairs;
}
}  // namespace

TEST(Association, InterpolatesAndCountsOutsideAndGaps)
{
	core::Trajectory gt, est;
	for (int i = 0; i <= 10; i++)
		if (i < 6 || i > 7) gt.push_back(pose(i, i, 0, 0));  // hole 5 s .. 8 s
	for (int i = 0; i < 12; i++) est.push_back(pose(i + 0.5, 0, 0, 0));
	const auto a = associateByInterpolation(gt, est);
	// 0.5..4.5 and 8.5, 9.5 pair; 5.5, 6.5, 7.5 in the gap; 10.5, 11.5 outside.
	EXPECT_EQ(a.pairs.size(), 7u);
	EXPECT_EQ(a.est_in_gt_gap, 3u);
	EXPECT_EQ(a.est_outside_gt, 2u);
	EXPECT_NEAR(a.pairs[1].gt.translation().x(), 1.5, 1e-12);
	EXPECT_NEAR(a.pairs[5].gt.translation().x(), 8.5, 1e-12);

	AssociationOptions loose;
	loose.max_gt_gap_s = 5;
	EXPECT_EQ(associateByInterpolation(gt, est, loose).pairs.size(), 10u);
}

TEST(Association, NoOverlapIsAnError)
{
	core::Trajectory gt = {pose(0, 0, 0, 0), pose(1, 1, 0, 0)};
	core::Trajectory est = {pose(5, 0, 0, 0), pose(6, 1, 0, 0)};
	try
	{
		associateByInterpolation(gt, est);
		FAIL() << "expected an exception";
	}
	catch (const std::runtime_error& e)
	{
		EXPECT_NE(std::string(e.what()).find("do not overlap in time"),
		          std::string::npos);
	}
}

TEST(Ate, SquareWithKnownOffset)
{
	const auto gt = square();
	auto est = gt;
	for (auto& p : est) p.pose.translation() += Eigen::Vector3d(0.3, -0.4, 0);
	const auto pairs = pairsOf(gt, est);
	const auto raw = absoluteTrajectoryError(pairs, false);
	EXPECT_EQ(raw.trans_m.count, 40u);
	EXPECT_NEAR(raw.trans_m.rmse, 0.5, 1e-12);
	EXPECT_NEAR(raw.trans_m.max, 0.5, 1e-12);
	EXPECT_NEAR(raw.rot_deg.max, 0.0, 1e-6);
	const auto al = absoluteTrajectoryError(pairs, true);
	EXPECT_NEAR(al.trans_m.rmse, 0.0, 1e-9);
	EXPECT_NEAR(al.alignment.translation().x(), -0.3, 1e-9);
	EXPECT_NEAR(al.alignment.translation().y(), 0.4, 1e-9);
}

TEST(Ate, HalfTheSquareLifted)
{
	// 20 of 40 poses 1 m too high: RMSE = sqrt(20 / 40), mean 0.5, median 0.5.
	const auto gt = square();
	auto est = gt;
	for (int i = 0; i < 20; i++) est[i].pose.translation().z() += 1.0;
	const auto raw = absoluteTrajectoryError(pairsOf(gt, est), false);
	EXPECT_NEAR(raw.trans_m.rmse, std::sqrt(0.5), 1e-12);
	EXPECT_NEAR(raw.trans_m.mean, 0.5, 1e-12);
	EXPECT_NEAR(raw.trans_m.median, 0.5, 1e-12);
}

TEST(Ate, RigidlyMovedSquareAlignsToZero)
{
	const auto gt = square();
	Eigen::Isometry3d M = Eigen::Isometry3d::Identity();
	M.linear() = Eigen::AngleAxisd(30 * kDeg, Eigen::Vector3d::UnitZ())
	                 .toRotationMatrix();
	M.translation() = Eigen::Vector3d(5, -2, 1);
	auto est = gt;
	for (auto& p : est) p.pose = M * p.pose;
	const auto pairs = pairsOf(gt, est);
	const auto raw = absoluteTrajectoryError(pairs, false);
	EXPECT_NEAR(raw.rot_deg.mean, 30.0, 1e-9);  // every pose rotated by 30 deg
	EXPECT_NEAR(raw.rot_deg.std, 0.0, 1e-6);
	EXPECT_GT(raw.trans_m.rmse, 1.0);
	const auto al = absoluteTrajectoryError(pairs, true);
	EXPECT_NEAR(al.trans_m.rmse, 0.0, 1e-9);
	EXPECT_NEAR(al.rot_deg.max, 0.0, 1e-6);
	EXPECT_TRUE(al.alignment.isApprox(M.inverse(), 1e-9));
}

TEST(Rpe, ScaleErrorIsOnePercent)
{
	// 200 m straight line, a pose per metre; estimate stretched by 1 %:
	// every segment of length L is 1.01 L long -> 1 % translational error.
	core::Trajectory gt, est;
	for (int i = 0; i <= 200; i++)
	{
		gt.push_back(pose(i, i, 0, 0));
		est.push_back(pose(i, 1.01 * i, 0, 0));
	}
	const auto r = relativePoseError(pairsOf(gt, est));
	// Segment of length L starts at 0..200-L: sum over L of (201 - L) = 1460.
	EXPECT_EQ(r.segments, 1460u);
	EXPECT_NEAR(r.trans_err_pct, 1.0, 1e-9);
	EXPECT_NEAR(r.rot_err_deg_per_m, 0.0, 1e-9);
	ASSERT_EQ(r.per_length.size(), 10u);
	EXPECT_EQ(r.per_length[0].segments, 191u);
	EXPECT_EQ(r.per_length[9].segments, 101u);
	EXPECT_NEAR(r.per_length[4].trans_err_pct, 1.0, 1e-9);
}

TEST(Rpe, KnownHeadingDrift)
{
	// Positions exact, heading drifting by 0.001 rad per metre: the relative
	// rotation of a segment of length L is 0.001 L rad -> 0.001 rad/m.
	core::Trajectory gt, est;
	for (int i = 0; i <= 150; i++)
	{
		gt.push_back(pose(i, i, 0, 0));
		est.push_back(pose(i, i, 0, 0, 0.001 * i / kDeg));
	}
	const auto r = relativePoseError(pairsOf(gt, est));
	EXPECT_NEAR(r.rot_err_deg_per_m, 0.001 / kDeg, 1e-9);
	for (const auto& l : r.per_length)
		EXPECT_NEAR(l.rot_err_deg_per_m, 0.001 / kDeg, 1e-9);
}

TEST(Rpe, TooShortGivesNoSegments)
{
	core::Trajectory gt, est;
	for (int i = 0; i <= 9; i++)
	{
		gt.push_back(pose(i, i, 0, 0));
		est.push_back(pose(i, i, 0, 0));
	}
	const auto r = relativePoseError(pairsOf(gt, est));
	EXPECT_EQ(r.segments, 0u);
	EXPECT_TRUE(std::isnan(r.trans_err_pct));
	RpeOptions o;
	o.lengths_m = {3};
	const auto r3 = relativePoseError(pairsOf(gt, est), o);
	EXPECT_EQ(r3.segments, 7u);  // starts 0..6
	EXPECT_NEAR(r3.trans_err_pct, 0.0, 1e-12);
}

TEST(VerticalDrift, OffsetIgnoredRiseAndFall)
{
	// 100 m flat GT; estimate starts 0.5 m high (offset, not drift), then
	// climbs 0.2 % over 50 m and sinks 0.1 % over the next 50 m:
	// max |e| = 0.1 m (0.1 %), end |e| = 0.05 m (0.05 %).
	core::Trajectory gt, est;
	for (int i = 0; i <= 100; i++)
	{
		gt.push_back(pose(i, i, 0, 0));
		const double e = i <= 50 ? 0.002 * i : 0.1 - 0.001 * (i - 50);
		est.push_back(pose(i, i, 0, 0.5 + e));
	}
	const auto v = verticalDrift(pairsOf(gt, est));
	EXPECT_NEAR(v.distance_m, 100.0, 1e-9);
	EXPECT_NEAR(v.max_abs_err_m, 0.1, 1e-9);
	EXPECT_NEAR(v.max_pct, 0.1, 1e-9);
	EXPECT_NEAR(v.end_abs_err_m, 0.05, 1e-9);
	EXPECT_NEAR(v.end_pct, 0.05, 1e-9);
}

TEST(ReturnToStart, PaperTable5Row)
{
	// Stand 1, proposed method: roll 5.68, pitch 3.95, yaw 6.14 -> total
	// 9.25 deg; x 0.48, y 0.33, z 1.54 -> total 1.65 m.
	const auto first = pose(0, 0, 0, 0);
	const auto last = pose(900, 0.48, 0.33, 1.54, 6.14, 3.95, 5.68);
	const auto e = returnToStartError(first, last);
	EXPECT_NEAR(e.roll_deg, 5.68, 1e-9);
	EXPECT_NEAR(e.pitch_deg, 3.95, 1e-9);
	EXPECT_NEAR(e.yaw_deg, 6.14, 1e-9);
	EXPECT_NEAR(e.total_rot_deg, 9.25, 0.005);
	EXPECT_NEAR(e.x_m, 0.48, 1e-12);
	EXPECT_NEAR(e.y_m, 0.33, 1e-12);
	EXPECT_NEAR(e.z_m, 1.54, 1e-12);
	EXPECT_NEAR(e.total_trans_m, 1.65, 0.005);
	// One rotation of three non-zero angles is shorter than their norm.
	EXPECT_LT(e.angle_deg, e.total_rot_deg);
	EXPECT_GT(e.angle_deg, 6.14);
	EXPECT_DOUBLE_EQ(e.t_last_s, 900);
}

TEST(ReturnToStart, FramesOfTheComponents)
{
	// First heading 90 deg: a 1 m step north is 1 m along the first heading
	// (x), and the yaw error is the 2 deg difference.
	const auto e =
	    returnToStartError(pose(0, 5, 5, 1, 90), pose(1, 5, 6, 1.2, 92));
	EXPECT_NEAR(e.x_m, 1.0, 1e-12);
	EXPECT_NEAR(e.y_m, 0.0, 1e-12);
	EXPECT_NEAR(e.z_m, 0.2, 1e-12);
	EXPECT_NEAR(e.yaw_deg, 2.0, 1e-9);
	EXPECT_NEAR(e.angle_deg, 2.0, 1e-9);
	EXPECT_NEAR(e.roll_deg, 0.0, 1e-9);

	// A sensor mounted with 20 deg roll: the 1 m altitude error stays z
	// (gravity), not split along the tilted sensor axes.
	const auto t = returnToStartError(pose(0, 0, 0, 0, 0, 0, 20),
	                                  pose(1, 0, 0, 1, 0, 0, 20));
	EXPECT_NEAR(t.z_m, 1.0, 1e-12);
	EXPECT_NEAR(t.y_m, 0.0, 1e-12);
	EXPECT_NEAR(t.angle_deg, 0.0, 1e-6);

	core::Trajectory traj = {pose(0, 0, 0, 0), pose(1, 3, 0, 0),
	                         pose(2, 0, 0, 4)};
	EXPECT_NEAR(returnToStartError(traj).total_trans_m, 4.0, 1e-12);
	EXPECT_THROW(returnToStartError(core::Trajectory{}), std::runtime_error);
}

TEST(ReturnToStart, RelativeToGtClosure)
{
	// GT itself ends 0.1 m higher and 1 deg left; the estimate 0.4 m and
	// 3 deg: its own error beyond the GT's is 0.3 m and 2 deg.
	const auto e = returnToStartErrorVsGt(
	    pose(0, 0, 0, 0), pose(9, 0, 0, 0.4, 3), pose(0, 0, 0, 0).pose,
	    pose(9, 0, 0, 0.1, 1).pose);
	EXPECT_NEAR(e.z_m, 0.3, 1e-12);
	EXPECT_NEAR(e.yaw_deg, 2.0, 1e-9);
	EXPECT_NEAR(e.total_trans_m, 0.3, 1e-12);
}

TEST(GnssDrift, EveryTenSecondsWithDropout)
{
	// Estimate walks +x at 1 m/s for 35 s; the GNSS reads 0.1 m/s of extra
	// northing and 2 m higher, and has no fix at t = 20 s.
	core::Trajectory est;
	for (int i = 0; i <= 350; i++) est.push_back(pose(0.1 * i, 0.1 * i, 0, 0));
	PositionTrack gnss;
	for (int t = 0; t <= 35; t++)
		if (t != 20)
			gnss.push_back({double(t), Eigen::Vector3d(t, 0.1 * t, 2)});
	const auto r = gnssDrift(est, gnss);
	EXPECT_EQ(r.sample_times, 4u);  // 0, 10, 20, 30
	EXPECT_EQ(r.skipped_no_fix, 1u);
	ASSERT_EQ(r.samples.size(), 3u);
	// Horizontal 0, 1, 3 m: mean 4/3, sample std sqrt(7/3).
	EXPECT_NEAR(r.dist_2d_m.mean, 4.0 / 3.0, 1e-9);
	EXPECT_NEAR(r.dist_2d_m.std, std::sqrt(7.0 / 3.0), 1e-9);
	EXPECT_NEAR(r.dist_2d_m.min, 0.0, 1e-9);
	EXPECT_NEAR(r.dist_2d_m.max, 3.0, 1e-9);
	// 3D: 2, sqrt(5), sqrt(13).
	EXPECT_NEAR(r.dist_3d_m.mean, (2 + std::sqrt(5.0) + std::sqrt(13.0)) / 3,
	            1e-9);
	EXPECT_NEAR(r.dist_3d_m.min, 2.0, 1e-9);
	EXPECT_NEAR(r.dist_3d_m.max, std::sqrt(13.0), 1e-9);

	// A fix 0.4 s late is used and compared with the estimate at its own
	// time (x = 10.4, so only the 0.5 m northing remains); one 0.7 s late is
	// a dropout.
	PositionTrack late = {{0.0, Eigen::Vector3d(0, 0, 0)},
	                      {10.4, Eigen::Vector3d(10.4, 0.5, 0)},
	                      {20.7, Eigen::Vector3d(20.7, 0, 0)},
	                      {30.0, Eigen::Vector3d(30, 0, 0)}};
	const auto l = gnssDrift(est, late);
	EXPECT_EQ(l.sample_times, 4u);
	EXPECT_EQ(l.skipped_no_fix, 1u);
	ASSERT_EQ(l.samples.size(), 3u);
	EXPECT_DOUBLE_EQ(l.samples[1].t_s, 10.4);
	EXPECT_NEAR(l.samples[1].dist_3d_m, 0.5, 1e-9);
	EXPECT_DOUBLE_EQ(l.samples[2].t_s, 30.0);
}

TEST(GnssDrift, AlignedFiguresAndErrors)
{
	core::Trajectory est;
	for (int i = 0; i <= 60; i++)
		est.push_back(pose(i, i, 0.02 * i * i, 0.1 * i));
	Eigen::Isometry3d M = Eigen::Isometry3d::Identity();
	M.linear() = Eigen::AngleAxisd(45 * kDeg, Eigen::Vector3d::UnitZ())
	                 .toRotationMatrix();
	M.translation() = Eigen::Vector3d(100, 200, 3);
	PositionTrack gnss;
	for (const auto& p : est) gnss.push_back({p.t_s, M * p.pose.translation()});
	const auto r = gnssDrift(est, gnss);
	EXPECT_EQ(r.samples.size(), 7u);
	EXPECT_GT(r.dist_3d_m.min, 100.0);
	EXPECT_NEAR(r.aligned_dist_3d_m.max, 0.0, 1e-6);

	PositionTrack later = {{100, Eigen::Vector3d::Zero()},
	                       {101, Eigen::Vector3d::Zero()}};
	EXPECT_THROW(gnssDrift(est, later), std::runtime_error);
}

TEST(Angles, RollPitchYawConvention)
{
	const auto p = pose(0, 0, 0, 0, -170, 30, 100);
	const auto rpy = rollPitchYawDeg(p.pose.linear());
	EXPECT_NEAR(rpy.x(), 100, 1e-9);
	EXPECT_NEAR(rpy.y(), 30, 1e-9);
	EXPECT_NEAR(rpy.z(), -170, 1e-9);
	EXPECT_NEAR(rotationAngleDeg(pose(0, 0, 0, 0, 0, 0, 179).pose.linear()),
	            179, 1e-9);
}
