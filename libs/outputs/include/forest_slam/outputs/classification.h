#pragma once
// Terrain, ground/vegetation/stem classes (ASPRS LAS 1.4 codes) and the
// ground DTM grid of the dense map.
#include <forest_slam/map/forest_map.h>
#include <forest_slam/outputs/dense_map.h>
#include <forest_slam/outputs/output_options.h>
#include <forest_slam/trees/terrain_model.h>

#include <Eigen/Core>
#include <functional>
#include <string>
#include <unordered_map>
#include <vector>

namespace forest_slam::ground
{
class GroundLattice;
}

namespace forest_slam::outputs
{
/** ASPRS LAS 1.4 R15 table 17 codes used by the outputs. */
enum LasClass : uint8_t
{
	kUnclassified = 1,
	kGround = 2,
	kLowVegetation = 3,
	kMediumVegetation = 4,
	kHighVegetation = 5,
	kLowNoise = 7,
};

/** Terrain under the dense map: the odometry's ground lattice sampled on a
 * grid over the cloud when there is one (the ground labels the pipeline
 * already computed), else the lowest-point DTM of libs/trees. */
trees::TerrainModel terrainForCloud(const std::vector<DensePoint>& pts,
                                    const ground::GroundLattice* lattice,
                                    const trees::TreeOptions& tree_opts);
/** Same over a DenseMap read tile by tile (with a lattice only the bounds
 * are needed; without one every point is loaded for the DTM). */
trees::TerrainModel terrainForCloud(const DenseMap& dense,
                                    const ground::GroundLattice* lattice,
                                    const trees::TreeOptions& tree_opts);

/** The rule of classifyPoints for one point at a time. */
class PointClassifier
{
   public:
	PointClassifier(const trees::TerrainModel& terrain,
	                const std::vector<map::TreeRecord>& trees,
	                const OutputOptions& o);
	uint8_t classify(const Eigen::Vector3d& p) const;

   private:
	const trees::TerrainModel& terrain_;
	const std::vector<map::TreeRecord>& trees_;
	const OutputOptions& o_;
	/** Stems indexed on a 1 m grid by every cell their circle + margin
	 * touches. */
	std::unordered_map<uint64_t, std::vector<size_t>> stem_cells_;
};

/** One LAS class per point by its height h above the terrain:
 * h < -3 ground_threshold: low noise (7); |h| <= ground_threshold: ground
 * (2); then low (3) / medium (4) / high (5) vegetation by the
 * *_vegetation_max_m limits; points within DBH/2 + stem_margin_m of a stem
 * centre and below stem_max_height_m: stem_class. */
std::vector<uint8_t> classifyPoints(const std::vector<DensePoint>& pts,
                                    const trees::TerrainModel& terrain,
                                    const std::vector<map::TreeRecord>& trees,
                                    const OutputOptions& o);

/** Regular grid of elevations, row iy = 0 at the south (min y) edge. */
struct ElevationGrid
{
	double x0 = 0, y0 = 0;  ///< lower-left corner of cell (0, 0)
	double cell_m = 1;
	int nx = 0, ny = 0;
	std::vector<double> z;  ///< nx*ny, NaN = no data
	double at(int ix, int iy) const { return z[ix + size_t(nx) * iy]; }
	size_t cellsWithData() const;
};

/** Mean elevation per cell of points added one at a time (output frame). */
class GroundGridBuilder
{
   public:
	explicit GroundGridBuilder(double cell_m) : cell_m_(cell_m) {}
	void add(const Eigen::Vector3d& p);
	/** Corner on a multiple of the cell; NaN where no point fell. */
	ElevationGrid grid() const;

   private:
	double cell_m_;
	struct Cell
	{
		double sum = 0;
		uint32_t n = 0;
	};
	std::unordered_map<uint64_t, Cell> cells_;
	int64_t ix_lo_ = 0, ix_hi_ = -1, iy_lo_ = 0, iy_hi_ = -1;
};

/** Mean elevation of the ground-class points per cell, in the output frame
 * given by `to_output` (identity or Georeference::toProjected). */
ElevationGrid groundGrid(
    const std::vector<DensePoint>& pts, const std::vector<uint8_t>& classes,
    double cell_m,
    const std::function<Eigen::Vector3d(const Eigen::Vector3d&)>& to_output);

/** ESRI ASCII grid (.asc), written atomically; NODATA_value -9999. */
void writeEsriAscii(const std::string& path, const ElevationGrid& g);

}  // namespace forest_slam::outputs
