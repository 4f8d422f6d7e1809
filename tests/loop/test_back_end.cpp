// The back-end on synthetic keyframes: a loop walked with yaw drift is
// closed and the end error falls; in a regular plantation the closure that
// would snap to the neighbouring row is refused; threaded and inline runs
// give identical poses (determinism).
#include "../support/file_size_limit.h"
#include "synthetic_forest.h"

#include <forest_slam/loop/back_end.h>
#include <forest_slam/loop/keyframe_cloud.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <iostream>
#include <stdexcept>
#include <string>

using namespace forest_slam::loop;
using namespace forest_slam::loop::test;

namespace
{
struct Walk
{
	std::vector<Eigen::Isometry3d> truth, odom;
	std::vector<double> travelled;
};

/** A circle of radius r walked in 1 m steps, odometry with yaw drift. */
Walk circle(double r, double drift_deg_per_m, double extra_m = 4)
{
	Walk w;
	const double len = 2 * M_PI * r + extra_m;
	Eigen::Isometry3d odom = Eigen::Isometry3d::Identity();
	for (double s = 0; s <= len; s += 1.0)
	{
		const double a = s / r;
		w.truth.push_back(poseXYZYaw(r * std::sin(a), r - r * std::cos(a), 1.5,
		                             a * 180 / M_PI));
		if (w.truth.size() == 1)
		{
			odom = w.truth[0];
		}
		else
		{
			const size_t i = w.truth.size() - 1;
			odom = odom * (w.truth[i - 1].inverse() * w.truth[i]) *
			       poseXYZYaw(0, 0, 0, drift_deg_per_m);
		}
		w.odom.push_back(odom);
		w.travelled.push_back(s);
	}
	return w;
}

LoopOptions options()
{
	LoopOptions o;
	o.enabled = true;
	o.min_travel_m = 20;
	o.detect_every_keyframes = 1;
	o.closure_spacing_keyframes = 3;
	o.submap_keyframes = 2;
	return o;
}

Poses run(const Walk& w, const std::vector<Stem>& stems, const LoopOptions& o,
          bool threaded, std::vector<Closure>* closures = nullptr,
          std::shared_ptr<forest_slam::core::SpillFile> spill = nullptr,
          size_t* cloud_bytes = nullptr)
{
	BackEnd b(o, threaded, spill);
	for (size_t i = 0; i < w.odom.size(); i++)
	{
		Keyframe kf;
		kf.stamp_s = static_cast<double>(i);
		kf.travelled_m = w.travelled[i];
		kf.odom_edge = i == 0 ? w.odom[0] : w.odom[i - 1].inverse() * w.odom[i];
		kf.cloud = voxelFilter(
		    sampleView(stems, w.truth[i], 15, 0.15, static_cast<unsigned>(i)),
		    o.cloud_voxel_m, o.cloud_max_range_m);
		b.addKeyframe(std::move(kf));
	}
	b.finish();
	if (closures) *closures = b.closures();
	if (cloud_bytes) *cloud_bytes = b.cloudBytes();
	return b.poses();
}
}  // namespace

TEST(BackEnd, ClosesADriftingLoopDeterministically)
{
	const auto stems = makeStems(5, 40);
	const Walk w = circle(6, 0.2);  // 8 deg over the loop
	const double before =
	    (w.odom.back().translation() - w.truth.back().translation()).norm();
	ASSERT_GT(before, 0.5);
	std::vector<Closure> closures;
	const Poses X = run(w, stems, options(), true, &closures);
	ASSERT_EQ(X.size(), w.truth.size());
	size_t accepted = 0;
	for (const auto& c : closures)
	{
		if (!c.accepted)
		{
			std::cout << "rejected " << c.from << " -> " << c.to << ": "
			          << c.reason << " overlap " << c.overlap << " rmse "
			          << c.rmse_m << " chi2 " << c.chi2 << "\n";
			continue;
		}
		accepted++;
		const Eigen::Isometry3d e =
		    (w.truth[c.from].inverse() * w.truth[c.to]).inverse() * c.T;
		EXPECT_LT(e.translation().norm(), 0.05);
	}
	EXPECT_GE(accepted, 1u);
	// Each closure's error is its disagreement with the estimate when it
	// was verified: the first one's is the drift round the loop.
	const auto first =
	    std::find_if(closures.begin(), closures.end(),
	                 [](const Closure& c) { return c.accepted; });
	ASSERT_NE(first, closures.end());
	EXPECT_GT(first->error_m, 0.3);
	EXPECT_GT(first->error_deg, 2.0);
	const double after =
	    (X.back().translation() - w.truth.back().translation()).norm();
	EXPECT_LT(after, 0.1) << "before " << before;
	// Same poses without the worker thread.
	const Poses Y = run(w, stems, options(), false);
	ASSERT_EQ(Y.size(), X.size());
	for (size_t i = 0; i < X.size(); i++)
		EXPECT_TRUE(X[i].isApprox(Y[i], 1e-12)) << "keyframe " << i;
}

TEST(BackEnd, VerificationThreadsDoNotChangeTheClosures)
{
	// The target's normals and the uniqueness re-runs on one thread or
	// three: the same closures (each re-run judged in order) and poses.
	const auto stems = makeStems(5, 40);
	const Walk w = circle(6, 0.2);
	LoopOptions one = options(), three = options();
	one.verify_threads = 1;
	three.verify_threads = 3;
	std::vector<Closure> a, b;
	const Poses X = run(w, stems, one, true, &a);
	const Poses Y = run(w, stems, three, true, &b);
	ASSERT_EQ(a.size(), b.size());
	ASSERT_FALSE(a.empty());
	for (size_t i = 0; i < a.size(); i++)
	{
		EXPECT_EQ(a[i].accepted, b[i].accepted) << i;
		EXPECT_EQ(a[i].reason, b[i].reason) << i;
		EXPECT_EQ(a[i].overlap, b[i].overlap) << i;
		EXPECT_TRUE(a[i].T.isApprox(b[i].T, 0)) << i;
	}
	ASSERT_EQ(X.size(), Y.size());
	for (size_t i = 0; i < X.size(); i++)
		EXPECT_TRUE(X[i].isApprox(Y[i], 0)) << "keyframe " << i;
}

TEST(BackEnd, SpilledKeyframeCloudsGiveTheSameClosures)
{
	// Old keyframe clouds on disk, read back for the candidates: the same
	// closures and poses as with every cloud in memory, and only the
	// newest few clouds (and those read back) left in memory.
	const auto stems = makeStems(5, 40);
	const Walk w = circle(6, 0.2);
	std::vector<Closure> in_memory, spilled;
	size_t bytes_memory = 0, bytes_spilled = 0;
	const Poses X =
	    run(w, stems, options(), true, &in_memory, nullptr, &bytes_memory);
	auto spill = std::make_shared<forest_slam::core::SpillFile>();
	const Poses Y =
	    run(w, stems, options(), true, &spilled, spill, &bytes_spilled);
	ASSERT_EQ(X.size(), Y.size());
	for (size_t i = 0; i < X.size(); i++)
		EXPECT_TRUE(X[i].isApprox(Y[i], 1e-12)) << "keyframe " << i;
	ASSERT_EQ(in_memory.size(), spilled.size());
	size_t accepted = 0;
	for (size_t i = 0; i < spilled.size(); i++)
	{
		EXPECT_EQ(in_memory[i].accepted, spilled[i].accepted) << i;
		EXPECT_EQ(in_memory[i].overlap, spilled[i].overlap) << i;
		accepted += spilled[i].accepted;
	}
	EXPECT_GE(accepted, 1u);
	EXPECT_GT(spill->size(), 0u);
	EXPECT_LT(bytes_spilled, bytes_memory / 2);
}

TEST(BackEnd, AWorkerFailureReachesTheCaller)
{
	// The keyframe clouds' spill file cannot grow (a full disk; here a file
	// size limit): the worker's error reaches the caller as an exception
	// naming the back-end, instead of an exception leaving the worker
	// thread, which aborts the process and loses the run.
	const auto stems = makeStems(5, 40);
	const Walk w = circle(6, 0.2);
	auto spill = std::make_shared<forest_slam::core::SpillFile>();
	std::string what;
	{
		const forest_slam::test::FileSizeLimit full_disk(4096);
		ASSERT_TRUE(full_disk.ok());
		try
		{
			run(w, stems, options(), true, nullptr, spill);
		}
		catch (const std::runtime_error& e)
		{
			what = e.what();
		}
	}
	EXPECT_EQ(what.rfind("back-end: cannot write the spill file", 0), 0u)
	    << what;
}

TEST(BackEnd, RefusesTheNeighbouringRowOfAPlantation)
{
	// Rows 3 m apart; the odometry's drift puts the end 2 m to the side, so
	// ICP from the estimate would snap onto the wrong row.
	const auto stems = makeStems(1, 40, true, 3.0);
	Walk w = circle(6, 0.0);
	for (size_t i = 0; i < w.odom.size(); i++)
		w.odom[i] =
		    poseXYZYaw(0, 2.0 * w.travelled[i] / w.travelled.back(), 0, 0) *
		    w.odom[i];
	std::vector<Closure> closures;
	run(w, stems, options(), true, &closures);
	ASSERT_FALSE(closures.empty());
	for (const auto& c : closures)
	{
		if (!c.accepted) continue;
		const Eigen::Isometry3d e =
		    (w.truth[c.from].inverse() * w.truth[c.to]).inverse() * c.T;
		EXPECT_LT(e.translation().norm(), 0.3)
		    << "false closure " << c.from << " -> " << c.to;
	}
}

TEST(BackEnd, DescriptorClosesALoopBeyondTheSearchRadius)
{
	// 1 deg/m of yaw drift: the end of the loop is metres from its start
	// in the estimate, beyond the geometric search radius.
	const auto stems = makeStems(5, 40);
	const Walk w = circle(6, 1.0);
	const double before =
	    (w.odom.back().translation() - w.truth.back().translation()).norm();
	LoopOptions o = options();
	// The geometric search confined to 1 m (the drift, 3.5 m, is beyond).
	o.search_radius_m = 1.0;
	o.search_drift_fraction = 0;
	ASSERT_GT(before, 3.0);
	o.descriptor = false;
	std::vector<Closure> closures;
	run(w, stems, o, false, &closures);
	for (const auto& c : closures) EXPECT_FALSE(c.accepted);
	o.descriptor = true;
	const Poses X = run(w, stems, o, false, &closures);
	size_t accepted = 0, by_descriptor = 0;
	for (const auto& c : closures)
	{
		std::cout << (c.descriptor ? "descriptor " : "geometric ") << c.from
		          << " -> " << c.to << ": "
		          << (c.accepted ? "accepted" : c.reason) << " distance "
		          << c.descriptor_distance << " overlap " << c.overlap
		          << " chi2 " << c.chi2 << "\n";
		if (!c.accepted) continue;
		accepted++;
		by_descriptor += c.descriptor;
		const Eigen::Isometry3d e =
		    (w.truth[c.from].inverse() * w.truth[c.to]).inverse() * c.T;
		EXPECT_LT(e.translation().norm(), 0.05);
	}
	// The descriptor closes the loop first; once the estimate is corrected
	// the geometric search may find the next ones.
	EXPECT_GE(by_descriptor, 1u);
	const double after =
	    (X.back().translation() - w.truth.back().translation()).norm();
	std::cout << "end error " << before << " m -> " << after << " m\n";
	EXPECT_LT(after, 0.2);
}

TEST(BackEnd, DescriptorRefusesThePlantationFarFromTheEstimate)
{
	// Rows 3 m apart; the estimate ends 9 m aside, the geometric search is
	// off (1 cm): only descriptor candidates, which find look-alike places
	// everywhere; none may be accepted at a wrong place. (With the
	// geometric search on, a candidate near the wrong estimate can pass:
	// the drift prior backs the estimate.)
	const auto stems = makeStems(1, 40, true, 3.0);
	Walk w = circle(6, 0.0);
	for (size_t i = 0; i < w.odom.size(); i++)
		w.odom[i] =
		    poseXYZYaw(0, 9.0 * w.travelled[i] / w.travelled.back(), 0, 0) *
		    w.odom[i];
	LoopOptions o = options();
	o.search_radius_m = 0.01;
	o.search_drift_fraction = 0;
	std::vector<Closure> closures;
	run(w, stems, o, false, &closures);
	size_t descriptor = 0;
	for (const auto& c : closures)
	{
		descriptor += c.descriptor;
		std::cout << (c.descriptor ? "descriptor " : "geometric ") << c.from
		          << " -> " << c.to << ": "
		          << (c.accepted ? "accepted" : c.reason) << " distance "
		          << c.descriptor_distance << " overlap " << c.overlap
		          << " rmse " << c.rmse_m << " chi2 " << c.chi2 << "\n";
		if (!c.accepted) continue;
		const Eigen::Isometry3d e =
		    (w.truth[c.from].inverse() * w.truth[c.to]).inverse() * c.T;
		EXPECT_LT(e.translation().norm(), 0.3)
		    << "false closure " << c.from << " -> " << c.to;
	}
	EXPECT_GT(descriptor, 0u);
}
