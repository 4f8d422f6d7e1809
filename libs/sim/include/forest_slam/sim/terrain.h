#pragma once
// Terrain: a smooth random height field (hills) plus a rough micro relief
// (forest floor), summed into one bilinear grid. A ray walks the cells of
// the smooth grid (2D DDA) and skips every cell whose highest surface node it
// passes above; in the few cells it dips below it walks the fine cells and
// intersects each bilinear patch exactly (a quadratic in the ray parameter).
#include <forest_slam/sim/options.h>
#include <forest_slam/sim/random.h>

#include <Eigen/Core>

#include <functional>
#include <vector>

namespace forest_slam::sim
{
/** A bilinear scalar field on a regular grid over [x0,x0+nx*step] x ... ;
 * queries outside clamp to the border. */
class GridField
{
   public:
	GridField() = default;
	GridField(double x0, double y0, double step, int nx, int ny);
	double& at(int ix, int iy)
	{
		return v_[static_cast<size_t>(iy) * nx_ + ix];
	}
	double at(int ix, int iy) const
	{
		return v_[static_cast<size_t>(iy) * nx_ + ix];
	}
	double value(double x, double y) const;
	/** d/dx, d/dy of the bilinear interpolant. */
	Eigen::Vector2d gradient(double x, double y) const;
	double minValue() const;
	double maxValue() const;
	int nx() const { return nx_; }
	int ny() const { return ny_; }
	double step() const { return step_; }
	double x0() const { return x0_; }
	double y0() const { return y0_; }
	double xOf(int ix) const { return x0_ + ix * step_; }
	double yOf(int iy) const { return y0_ + iy * step_; }

   private:
	double x0_ = 0, y0_ = 0, step_ = 1, inv_step_ = 1;
	int nx_ = 0, ny_ = 0;
	std::vector<double> v_;
};

struct TerrainStats
{
	double elevation_range_m = 0;  ///< peak-to-peak of the smooth field
	double max_slope_deg = 0;
};

class Terrain
{
   public:
	/** Bounds of the world [xmin,xmax] x [ymin,ymax]. The field is shifted so
	 * that the smooth height at (0,0) is 0. `flat_radius` around (0,0) is
	 * levelled (the open yard at the start), blending over `flat_blend_m`.
	 * `roughness_factor(x,y)` in [0,1] scales the micro relief (trail). */
	Terrain(const TerrainOptions& o, double xmin, double ymin, double xmax,
	        double ymax, double flat_radius_m, double flat_blend_m,
	        const std::function<double(double, double)>& roughness_factor,
	        Rng& rng);

	/** Full surface height (hills + micro relief): bilinear on the micro
	 * relief grid of (smooth + rough), which is the sum of the two bilinear
	 * fields when the grid steps divide each other (the defaults do). */
	double height(double x, double y) const { return full_.value(x, y); }
	/** Hills only: what a vehicle or a walker follows. */
	double smoothHeight(double x, double y) const
	{
		return smooth_.value(x, y);
	}
	Eigen::Vector2d smoothGradient(double x, double y) const
	{
		return smooth_.gradient(x, y);
	}
	/** Upward unit normal of the full surface. */
	Eigen::Vector3d normal(double x, double y) const;

	/** First intersection with t in (0, t_max] of o + t d (|d| = 1). */
	bool raycast(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
	             double t_max, double& t_hit) const;

	/** Lower bound of the surface over [x0,x1] x [y0,y1]. */
	double minHeightIn(double x0, double y0, double x1, double y1) const;

	const TerrainStats& stats() const { return stats_; }
	double maxHeight() const { return max_h_; }

   private:
	GridField smooth_;  ///< hills, for vehicles and walkers
	GridField full_;    ///< hills + micro relief, on the micro relief grid
	std::vector<float> cell_max_;  ///< upper bound per smooth grid cell
	bool marchCell(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
	               double t0, double t1, double& t_hit) const;
	double max_h_ = 0;
	TerrainStats stats_;
};

}  // namespace forest_slam::sim
