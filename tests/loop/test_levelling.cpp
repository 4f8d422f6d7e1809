#include <forest_slam/loop/levelling.h>
#include <gtest/gtest.h>

#include <random>

using namespace forest_slam::loop;

namespace
{
Eigen::Matrix3d rot(const Eigen::Vector3d& axis, double deg)
{
	return Eigen::AngleAxisd(deg * M_PI / 180, axis.normalized())
	    .toRotationMatrix();
}

/** Keyframes of a walk in a map frame tilted by `tilt` (true gravity up
 * in map coordinates is tilt^T z), their "up" measured with a bias fixed
 * in the sensor frame and white noise. */
struct Walk
{
	std::vector<Eigen::Matrix3d> R;
	std::vector<std::optional<Eigen::Vector3d>> up;
};
Walk makeWalk(const Eigen::Matrix3d& tilt, const Eigen::Vector3d& bias,
              double yaw_span_deg, size_t n, double noise_deg, int seed)
{
	std::mt19937 rng(seed);
	std::normal_distribution<double> N(0, noise_deg * M_PI / 180);
	Walk w;
	for (size_t k = 0; k < n; k++)
	{
		const double yaw = yaw_span_deg * k / n;
		// Sensor orientation in the true (levelled) frame: yaw plus a gait
		// sway of a few degrees.
		const Eigen::Matrix3d R_true = rot({0, 0, 1}, yaw) *
		                               rot({1, 0, 0}, 3 * std::sin(0.7 * k)) *
		                               rot({0, 1, 0}, 2 * std::cos(0.3 * k));
		// Measured up: gravity up in the sensor frame, plus the bias.
		Eigen::Vector3d u = R_true.transpose() * Eigen::Vector3d::UnitZ();
		u = (u + bias + Eigen::Vector3d(N(rng), N(rng), N(rng))).normalized();
		w.R.push_back(tilt * R_true);  // the map is tilted
		w.up.push_back(u);
	}
	return w;
}

double angleDeg(const Eigen::Matrix3d& R)
{
	return Eigen::AngleAxisd(R).angle() * 180 / M_PI;
}
}  // namespace

TEST(Levelling, SeparatesTheMapTiltFromTheAccelerometerBias)
{
	// The forest-sim's accelerometer bias (0.03 m/s^2 per axis) tilts "up"
	// by ~0.2 deg in the sensor frame; the map is tilted by 0.3 deg.
	const Eigen::Matrix3d tilt = rot({1, 2, 0}, 0.3);
	const Eigen::Vector3d bias(0.003, -0.003, 0);
	// Headings over three quarters of a turn: the bias does not average
	// out of the mean "up".
	const Walk w = makeWalk(tilt, bias, 270, 600, 0.3, 1);
	const Levelling L = estimateLevelling(w.R, w.up);
	ASSERT_TRUE(L.ok);
	EXPECT_EQ(L.used + L.rejected, 600u);
	// L.R undoes the tilt: (L.R * tilt) is a rotation about z only.
	const Eigen::Vector3d z = L.R * tilt * Eigen::Vector3d::UnitZ();
	EXPECT_LT(std::acos(z.z()) * 180 / M_PI, 0.04);
	EXPECT_NEAR(L.tilt_deg, 0.3, 0.04);
	// The bias is found in the sensor frame (0.17 deg per axis).
	EXPECT_NEAR(L.bias_deg.x(), 0.003 * 180 / M_PI, 0.03);
	EXPECT_NEAR(L.bias_deg.y(), -0.003 * 180 / M_PI, 0.03);
	// The mean "up" of the run (the bias not modelled) is off by a part of
	// the bias, the first keyframe's by all of it (levelling at the first
	// scan).
	const Eigen::Vector3d truth = tilt * Eigen::Vector3d::UnitZ();
	Eigen::Vector3d mean = Eigen::Vector3d::Zero();
	for (size_t k = 0; k < w.R.size(); k++) mean += w.R[k] * *w.up[k];
	EXPECT_GT(std::acos(mean.normalized().dot(truth)) * 180 / M_PI, 0.06);
	const Eigen::Vector3d first = (w.R[0] * *w.up[0]).normalized();
	EXPECT_GT(std::acos(first.dot(truth)) * 180 / M_PI, 0.1);
}

TEST(Levelling, AStraightPathKeepsTheMeanUp)
{
	// One heading: bias and tilt look alike; the prior holds the bias, and
	// the map takes the mean "up" (no worse than the first scan's).
	const Eigen::Matrix3d tilt = rot({1, 0, 0}, 0.2);
	const Walk w = makeWalk(tilt, Eigen::Vector3d::Zero(), 0, 300, 0.3, 2);
	const Levelling L = estimateLevelling(w.R, w.up);
	ASSERT_TRUE(L.ok);
	const Eigen::Vector3d z = L.R * tilt * Eigen::Vector3d::UnitZ();
	EXPECT_LT(std::acos(z.z()) * 180 / M_PI, 0.05);
	// A rotation about a horizontal axis only: the first heading stays.
	const Eigen::Vector3d x = L.R * Eigen::Vector3d::UnitX();
	EXPECT_NEAR(std::atan2(x.y(), x.x()), 0, 1e-3);
	EXPECT_LT(angleDeg(L.R), 0.3);
}

TEST(Levelling, NeedsEnoughKeyframesAndIgnoresBrokenSamples)
{
	const Walk few = makeWalk(Eigen::Matrix3d::Identity(),
	                          Eigen::Vector3d::Zero(), 360, 10, 0.3, 3);
	EXPECT_FALSE(estimateLevelling(few.R, few.up).ok);
	Walk w = makeWalk(rot({0, 1, 0}, 0.25), Eigen::Vector3d::Zero(), 360, 200,
	                  0.3, 4);
	// No IMU at some keyframes, a NaN and a sample pointing sideways.
	for (size_t k = 0; k < 20; k++) w.up[k * 10].reset();
	w.up[5] = Eigen::Vector3d(NAN, 0, 1);
	w.up[7] = Eigen::Vector3d(1, 0, 0);
	// A few keyframes measured while the sensor accelerated: 3 deg off.
	for (size_t k = 101; k < 106; k++)
		w.up[k] = (rot({1, 0, 0}, 3) * *w.up[k]).normalized();
	const Levelling L = estimateLevelling(w.R, w.up);
	ASSERT_TRUE(L.ok);
	EXPECT_EQ(L.used + L.rejected, 178u);
	EXPECT_GE(L.rejected, 5u);
	EXPECT_NEAR(L.tilt_deg, 0.25, 0.03);
}
