#pragma once
// Synthetic VLP-16 scans of a simple world (flat ground z=-1.5, walls
// x=+-wall_x and a few vertical poles) seen from a sensor moving along +x at constant speed, each
// column fired at its own time: enough to test deskew and the pipeline
// without the simulator.
#include <forest_slam/core/lidar_model.h>
#include <forest_slam/core/scan_points.h>
#include <forest_slam/core/trajectory.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/system/datetime.h>

#include <cmath>
#include <limits>
#include <vector>

namespace forest_slam::test_support
{
struct MovingSensorWorld
{
	double speed_mps = 2.0;
	double wall_x = 12.0;
	double ground_z = -1.5;
	double t0_s = 1000.0;
	double period_s = 0.1;
	int columns = 900;
	double pole_radius_m = 0.15;
	std::vector<Eigen::Vector2d> poles = {{5, 4}, {-6, -5}, {8, -6}, {-3, 6}, {2, -4}};

	Eigen::Vector3d positionAt(double t) const
	{
		return {speed_mps * (t - t0_s), 0, 0};
	}

	mrpt::obs::CObservationRotatingScan scan(int k) const
	{
		const auto& m = core::lidarModelByName("VLP16");
		mrpt::obs::CObservationRotatingScan s;
		s.sensorLabel = "lidar";
		s.lidarModel = "VLP16";
		s.rowCount = 16;
		s.columnCount = columns;
		s.rangeImage.setZero(16, columns);
		s.intensityImage.setZero(16, columns);
		s.rangeResolution = 0.002;
		s.startAzimuth = -M_PI;
		s.azimuthSpan = 2 * M_PI * (columns - 1) / columns;
		s.sweepDuration = period_s * (columns - 1) / columns;
		s.minRange = 0.5;
		s.maxRange = 100;
		const double ts = t0_s + k * period_s;
		s.timestamp = mrpt::Clock::fromDouble(ts);
		for (int c = 0; c < columns; c++)
		{
			const double az = core::columnAzimuth(s, c);
			const double t = ts + core::columnTime(s, c);
			const Eigen::Vector3d o = positionAt(t);
			for (int r = 0; r < 16; r++)
			{
				const double el = m.elevation_rad[r];
				const Eigen::Vector3d d(std::cos(el) * std::cos(az),
										std::cos(el) * std::sin(az), std::sin(el));
				double best = std::numeric_limits<double>::infinity();
				if (std::abs(d.x()) > 1e-6)
				{
					// Walls at +wall_x (ahead) and -wall_x (behind: seen at
					// the start and the end of the sweep, 0.1 s apart).
					const double tw = ((d.x() > 0 ? wall_x : -wall_x) - o.x()) / d.x();
					const Eigen::Vector3d hit = o + tw * d;
					if (tw > 0 && std::abs(hit.y()) < 8 && hit.z() > ground_z)
						best = tw;
				}
				// Vertical poles (stems): they constrain the motion along
				// the walls, which walls and ground alone leave free.
				for (const auto& pole : poles)
				{
					const Eigen::Vector2d o2(o.x() - pole.x(), o.y() - pole.y());
					const Eigen::Vector2d d2(d.x(), d.y());
					const double a = d2.squaredNorm(), b = o2.dot(d2),
								 cc = o2.squaredNorm() - pole_radius_m * pole_radius_m;
					const double disc = b * b - a * cc;
					if (a < 1e-12 || disc < 0) continue;
					const double tp = (-b - std::sqrt(disc)) / a;
					if (tp > 0 && tp < best && o.z() + tp * d.z() > ground_z) best = tp;
				}
				if (d.z() < -1e-6)
				{
					const double tg = (ground_z - o.z()) / d.z();
					if (tg > 0 && tg < best) best = tg;
				}
				if (best < 60)
					s.rangeImage(r, c) = static_cast<uint16_t>(
						std::lround(best / s.rangeResolution));
			}
		}
		return s;
	}

	core::Trajectory groundTruth(int scans) const
	{
		core::Trajectory tr;
		for (int i = 0; i <= scans * 10; i++)
		{
			core::StampedPose p;
			p.t_s = t0_s + i * period_s / 10;
			p.pose.translation() = positionAt(p.t_s);
			tr.push_back(p);
		}
		return tr;
	}
};

}  // namespace forest_slam::test_support
