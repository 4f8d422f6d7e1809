#pragma once
// Terrain elevation under the stems, so that slices and DBH are taken at a
// height above the *local* ground even on slopes (paper §6.2, issue 7).
// A regular grid with bilinear interpolation: the standalone mode fills it
// from the cloud (buildDtm), the SLAM pipeline from its ground lattice.
#include <forest_slam/trees/tree_options.h>

#include <Eigen/Core>

#include <vector>

namespace forest_slam::trees
{
class TerrainModel
{
   public:
	TerrainModel() = default;
	/** nx × ny cells of `cell_m`, cell (0,0) centred at (x0, y0); heights
	 * row-major (ix + nx*iy), NaN for "unknown" (filled from neighbours). */
	TerrainModel(double x0, double y0, double cell_m, int nx, int ny,
	             std::vector<double> heights);

	/** Ground elevation at (x, y): bilinear between cell centres, clamped to
	 * the grid border outside it. Throws std::logic_error if empty. */
	double heightAt(double x, double y) const;
	double heightAboveGround(const Eigen::Vector3d& p) const
	{
		return p.z() - heightAt(p.x(), p.y());
	}

	bool empty() const { return h_.empty(); }
	int nx() const { return nx_; }
	int ny() const { return ny_; }
	double cellSize() const { return cell_m_; }
	double cell(int ix, int iy) const { return h_[ix + nx_ * iy]; }

   private:
	double x0_ = 0, y0_ = 0, cell_m_ = 1;
	int nx_ = 0, ny_ = 0;
	std::vector<double> h_;
};

/** DTM of a standalone cloud: lowest point per cell, then cells standing more
 * than dtm_max_step_m above the median of their neighbourhood are dropped
 * (stem bases, shrubs, boulders: a cell fully covered by them never sees the
 * ground) as are cells far below it (noise under the ground), and the holes
 * are filled from neighbouring cells. Throws std::invalid_argument if empty. */
TerrainModel buildDtm(const std::vector<Eigen::Vector3d>& pts,
                      const TreeOptions& o);

}  // namespace forest_slam::trees
