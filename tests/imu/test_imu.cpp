#include <forest_slam/imu/imu_buffer.h>
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

using namespace forest_slam;

namespace
{
/** A body tilted by `tilt` (roll about x), spinning about its own z at rate
 * w, sampled at 200 Hz with a constant gyro bias and white noise. */
struct SpinningImu
{
	double tilt = 0.2, w = 0.5;
	Eigen::Vector3d bias{0.01, -0.02, 0.005};
	std::mt19937 rng{3};
	std::normal_distribution<double> n{0.0, 1.0};
	void fill(imu::ImuBuffer& b, double t0, double t1, double gyro_sigma = 1e-3,
	          double acc_sigma = 0.02)
	{
		for (double t = t0; t <= t1 + 1e-9; t += 0.005)
		{
			// Specific force at rest: +g along world z, seen in the body.
			const Eigen::Matrix3d R_wb =
			    Eigen::AngleAxisd(tilt, Eigen::Vector3d::UnitX()) *
			    Eigen::AngleAxisd(w * t, Eigen::Vector3d::UnitZ())
			        .toRotationMatrix();
			const Eigen::Vector3d acc =
			    R_wb.transpose() * Eigen::Vector3d(0, 0, 9.80665) +
			    acc_sigma * Eigen::Vector3d(n(rng), n(rng), n(rng));
			const Eigen::Vector3d gyro =
			    Eigen::Vector3d(0, 0, w) + bias +
			    gyro_sigma * Eigen::Vector3d(n(rng), n(rng), n(rng));
			ASSERT_TRUE(b.add(t, gyro, acc));
		}
	}
};
}  // namespace

TEST(Imu, AttitudeLevelsWithGravityAndLearnsTheGyroBias)
{
	imu::AttitudeOptions o;
	o.kp = 1.0;
	o.ki = 0.1;
	imu::ImuBuffer b(o);
	SpinningImu s;
	s.fill(b, 0.0, 60.0);
	Eigen::Quaterniond q;
	ASSERT_TRUE(b.attitudeAt(60.0, q));
	// "Up" in the body frame must match the truth within 0.3 deg.
	const Eigen::Matrix3d R_wb =
	    Eigen::AngleAxisd(s.tilt, Eigen::Vector3d::UnitX()) *
	    Eigen::AngleAxisd(s.w * 60.0, Eigen::Vector3d::UnitZ())
	        .toRotationMatrix();
	const Eigen::Vector3d up_true = R_wb.transpose() * Eigen::Vector3d::UnitZ();
	const Eigen::Vector3d up_est = q.conjugate() * Eigen::Vector3d::UnitZ();
	EXPECT_LT(std::acos(std::min(1.0, up_true.dot(up_est))) * 180 / M_PI, 0.3);
	// Roll and pitch bias components are observable from gravity.
	EXPECT_NEAR(b.filter().gyroBias().x(), s.bias.x(), 3e-3);
	EXPECT_NEAR(b.filter().gyroBias().y(), s.bias.y(), 3e-3);
}

TEST(Imu, AStartAtRestGivesTheGyroBiasYawIncluded)
{
	// 2 s at rest, tilted, then spinning: the mean gyro at rest is the
	// bias, yaw's too (gravity gives roll and pitch only).
	const auto run = [](bool standstill_bias)
	{
		imu::AttitudeOptions o;
		o.standstill_bias = standstill_bias;
		auto b = std::make_unique<imu::ImuBuffer>(o);
		SpinningImu s;
		s.w = 0;
		s.fill(*b, 0.0, 2.0);
		EXPECT_EQ(b->filter().atRestSinceStart(), standstill_bias);
		return b;
	};
	const SpinningImu truth;
	auto b = run(true);
	EXPECT_NEAR(b->filter().gyroBias().z(), truth.bias.z(), 3e-4);
	EXPECT_LT((b->filter().gyroBias() - truth.bias).norm(), 5e-4);
	// Without it the yaw bias stays unknown.
	EXPECT_GT(std::abs(run(false)->filter().gyroBias().z() - truth.bias.z()),
	          4e-3);
	// Then the rig turns: the estimate stays, and a second of spin is
	// integrated within a tenth of the bias' effect.
	SpinningImu spin;
	spin.w = 0.5;
	for (double t = 2.005; t <= 4.0 + 1e-9; t += 0.005)
	{
		const Eigen::Vector3d gyro = Eigen::Vector3d(0, 0, spin.w) + spin.bias;
		const Eigen::Matrix3d R_wb =
		    Eigen::AngleAxisd(spin.tilt, Eigen::Vector3d::UnitX()) *
		    Eigen::AngleAxisd(spin.w * (t - 2.0), Eigen::Vector3d::UnitZ())
		        .toRotationMatrix();
		ASSERT_TRUE(
		    b->add(t, gyro, R_wb.transpose() * Eigen::Vector3d(0, 0, 9.80665)));
	}
	EXPECT_FALSE(b->filter().atRestSinceStart());
	EXPECT_NEAR(b->filter().gyroBias().z(), truth.bias.z(), 5e-4);
	EXPECT_NEAR(Eigen::AngleAxisd(b->rotationBetween(2.5, 3.5)).angle(), 0.5,
	            0.1 * truth.bias.z());
}

TEST(Imu, ASlowTurnFromTheStartIsNotTakenForABias)
{
	// 5 deg/s about z from the first sample: steady, but beyond
	// standstill_max_bias_deg_s.
	imu::AttitudeOptions o;
	o.standstill_bias = true;
	imu::ImuBuffer b(o);
	SpinningImu s;
	s.w = 5 * M_PI / 180;
	s.bias.setZero();
	s.fill(b, 0.0, 0.5, 0.0, 0.0);
	EXPECT_LT(b.filter().gyroBias().norm(), 1e-4);
}

TEST(Imu, RotationBetweenIntegratesTheGyro)
{
	imu::ImuBuffer b;
	SpinningImu s;
	s.bias.setZero();
	s.fill(b, 0.0, 2.0, 0.0, 0.0);
	ASSERT_TRUE(b.covers(0.5, 1.5));
	EXPECT_FALSE(b.covers(0.5, 2.5));
	const Eigen::AngleAxisd d(b.rotationBetween(0.5, 1.5));
	EXPECT_NEAR(d.angle(), s.w * 1.0, 1e-4);  // the filter learns a tiny bias
	EXPECT_NEAR(std::abs(d.axis().z()), 1.0, 1e-6);
	// Sub-sample boundaries are interpolated.
	EXPECT_NEAR(Eigen::AngleAxisd(b.rotationBetween(0.5012, 0.5037)).angle(),
	            s.w * 0.0025, 1e-6);
}

TEST(Imu, RejectsBadSamplesAndGaps)
{
	imu::ImuBuffer b;
	const Eigen::Vector3d g(0, 0, 9.8), z = Eigen::Vector3d::Zero();
	EXPECT_TRUE(b.add(1.0, z, g));
	EXPECT_FALSE(b.add(0.9, z, g)) << "time going backwards";
	EXPECT_FALSE(b.add(1.0, z, g)) << "duplicate time";
	EXPECT_FALSE(b.add(1.1, Eigen::Vector3d(NAN, 0, 0), g));
	EXPECT_TRUE(b.add(1.005, z, g));
	EXPECT_TRUE(b.add(2.0, z, g));  // a 1 s IMU stall
	EXPECT_TRUE(b.covers(1.0, 1.005));
	EXPECT_FALSE(b.covers(1.0, 2.0))
	    << "a gap longer than max_gap_s is not covered";
	b.pruneBefore(1.9);
	EXPECT_FALSE(b.covers(1.0, 1.005));
}

namespace
{
/** Tilt error [deg] of a filter fed with a walking gait: a level rig moving
 * along x, bobbing vertically at the step frequency (±7 m/s², as on the
 * forest-sim handheld rig) with a small forward surge in phase with the bob,
 * plus a gyro bias. Returns the RMS over the last 30 of 60 s. */
double gaitTiltErrorDeg(const imu::AttitudeOptions& o)
{
	imu::AttitudeFilter f(o);
	const Eigen::Vector3d bias(0.003, -0.002, 0.001);
	const double step_hz = 1.8, dt = 0.005;
	double sum2 = 0;
	int n = 0;
	for (double t = 0; t < 60.0; t += dt)
	{
		const double ph = 2 * M_PI * step_hz * t;
		// The rig stands still for the first second (levelling), then walks.
		const double walk = t < 1.0 ? 0.0 : 1.0;
		const Eigen::Vector3d acc(walk * 0.6 * std::sin(ph), 0.0,
		                          9.80665 + walk * 7.0 * std::sin(ph));
		f.update(bias, acc, dt);
		if (t < 30.0 || !f.initialised()) continue;
		const Eigen::Vector3d up =
		    f.attitude().conjugate() * Eigen::Vector3d::UnitZ();
		const double e = std::acos(std::min(1.0, up.z())) * 180 / M_PI;
		sum2 += e * e;
		n++;
	}
	return std::sqrt(sum2 / std::max(1, n));
}
}  // namespace

TEST(Imu, WalkingGaitDoesNotTiltTheAttitude)
{
	// Forward surge correlated with the vertical bob averages to zero as a
	// vector, but not as a direction: a filter that normalises each sample
	// leans forward (this was 5 deg RMS on the simulated handheld walk).
	imu::AttitudeOptions o;
	const double lowpassed = gaitTiltErrorDeg(o);
	EXPECT_LT(lowpassed, 0.4);
	o.accel_lowpass_s = 0;  // each sample's direction on its own
	const double per_sample = gaitTiltErrorDeg(o);
	EXPECT_GT(per_sample, 1.0);
	std::printf("gait tilt RMS: low-passed %.3f deg, per sample %.3f deg\n",
	            lowpassed, per_sample);
}

TEST(Imu, IntegrateAccelerationFollowsASwingingSpinningBody)
{
	// A hand-held rig: it swings sideways and bobs at gait frequency while
	// it turns about z at 0.5 rad/s (tilted 0.2 rad). Position, velocity and
	// specific force in closed form; the integral over a sweep-sized window
	// must give the velocity change, the displacement and the moment
	// (v(t1) minus the mean velocity) in the body frame at t0.
	const double w = 2 * M_PI * 1.8, A = 0.05, B = 0.03, yaw_rate = 0.5,
	             tilt = 0.2;
	const Eigen::Vector3d g_w(0, 0, -9.80665);
	auto R_wb = [&](double t)
	{
		return (Eigen::AngleAxisd(tilt, Eigen::Vector3d::UnitX()) *
		        Eigen::AngleAxisd(yaw_rate * t, Eigen::Vector3d::UnitZ()))
		    .toRotationMatrix();
	};
	auto p = [&](double t)
	{
		return Eigen::Vector3d(A * std::sin(w * t), 0.8 * t,
		                       B * std::sin(2 * w * t));
	};
	auto v = [&](double t)
	{
		return Eigen::Vector3d(A * w * std::cos(w * t), 0.8,
		                       2 * B * w * std::cos(2 * w * t));
	};
	auto a = [&](double t)
	{
		return Eigen::Vector3d(-A * w * w * std::sin(w * t), 0,
		                       -4 * B * w * w * std::sin(2 * w * t));
	};
	imu::ImuBuffer b;
	for (double t = 0; t <= 3.0 + 1e-9; t += 0.005)
		ASSERT_TRUE(b.add(t, Eigen::Vector3d(0, 0, yaw_rate),
		                  R_wb(t).transpose() * (a(t) - g_w)));
	for (const double t0 : {1.0, 1.2371, 2.05})
	{
		const double t1 = t0 + 0.1;
		ASSERT_TRUE(b.covers(t0, t1));
		const Eigen::Matrix3d Rt = R_wb(t0).transpose();
		const imu::AccelIntegral got =
		    b.integrateAcceleration(t0, t1, Rt * g_w);
		const Eigen::Vector3d dv = Rt * (v(t1) - v(t0));
		const Eigen::Vector3d dp = Rt * (p(t1) - p(t0) - v(t0) * (t1 - t0));
		const Eigen::Vector3d moment =
		    Rt * (v(t1) - (p(t1) - p(t0)) / (t1 - t0));
		EXPECT_LT((got.dv - dv).norm(), 2e-3) << "t0 " << t0;
		EXPECT_LT((got.dp - dp).norm(), 1e-4) << "t0 " << t0;
		EXPECT_LT((got.moment - moment).norm(), 2e-3) << "t0 " << t0;
		// Not trivially small: the swing changes the velocity by dm/s.
		EXPECT_GT(dv.norm(), 0.05) << "t0 " << t0;
	}
	// Level and at rest: nothing moves.
	imu::ImuBuffer rest;
	for (double t = 0; t <= 1.0 + 1e-9; t += 0.005)
		ASSERT_TRUE(rest.add(t, Eigen::Vector3d::Zero(), -g_w));
	const imu::AccelIntegral z = rest.integrateAcceleration(0.3, 0.4, g_w);
	EXPECT_LT(z.dv.norm() + z.dp.norm() + z.moment.norm(), 1e-9);
}
