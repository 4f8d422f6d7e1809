#pragma once
// Builds the forest around a planned route: terrain (levelled yard at the
// start, compacted trail), trees by a hard-core point process with lognormal
// DBH, taper, lean, elliptic rough stems, whorls of branches and see-through
// crowns; saplings; shrub patches; buildings and vehicles in the yard.
// Nothing solid is placed on the route itself.
#include <forest_slam/sim/motion_planner.h>
#include <forest_slam/sim/options.h>
#include <forest_slam/sim/world.h>

#include <Eigen/Core>

#include <memory>
#include <vector>

namespace forest_slam::sim
{
/** Ground truth of one tree (or sapling), world frame. */
struct TreeTruth
{
	int id = 0;                 ///< 0-based; the gt_tree layer stores id + 1
	Eigen::Vector3d ground;     ///< stem axis at the ground (x, y, z_ground)
	Eigen::Vector2d breast_xy;  ///< stem axis 1.3 m above z_ground
	double dbh_m = 0;  ///< 2 x mean radius at 1.3 m (0: sapling < 1.3 m)
	double height_m = 0, lean_deg = 0, ellipticity = 0;
	bool sapling = false;
};

struct SceneStats
{
	double forest_area_ha = 0;
	int trees = 0, saplings = 0, shrubs = 0, buildings = 0, vehicles = 0;
	double stems_per_ha = 0;  ///< trees (not saplings) per forested hectare
	double shrub_cover = 0;   ///< fraction of the forested area
	double terrain_elevation_range_m = 0, terrain_max_slope_deg = 0;
};

/** Distance from points of the plane to a set of path samples, on a grid,
 * capped at `cap_m` (values beyond are cap_m). */
class PathDistance
{
   public:
	PathDistance(const std::vector<Eigen::Vector2d>& samples, double xmin,
	             double ymin, double xmax, double ymax, double cell_m,
	             double cap_m);
	double operator()(double x, double y) const;

   private:
	double x0_, y0_, inv_, cap_;
	int nx_, ny_;
	std::vector<float> d_;
};

struct Scene
{
	std::unique_ptr<World> world;
	std::vector<TreeTruth> trees;
	SceneStats stats;
};

Scene buildScene(const SimOptions& o, const PathPlan& path, Rng& rng);

}  // namespace forest_slam::sim
