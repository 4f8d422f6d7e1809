#pragma once
// The odometry's own local map for scan-to-map matching: incremental, so no
// search structure is rebuilt as the sensor moves (rebuilding k-d trees over
// the local map was most of a scan's time).
//  - planar and edge points: hashes of cells holding points at least a
//    spacing apart; the k nearest points from the 27 cells around a query
//    give the plane (or line). Planes from nearby points follow curved
//    surfaces such as stems, whose silhouette "edges" move with the view.
//  - coarse plane voxels keep running sums (count, mean, scatter) and fit
//    their plane when points were added: the fallback where the points are
//    too sparse.
// Voxels far from the sensor are dropped (prune); the CForestMap keeps the
// full map.
#include <forest_slam/core/flat_hash_map.h>
#include <forest_slam/odometry/feature_registration.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

namespace forest_slam::odometry
{
struct LocalMapOptions : public mrpt::config::CLoadableOptions
{
	/** Cells of the point hashes; at least twice [registration]
	 * max_neighbourhood_m, a k-NN search then visits at most 8 cells. */
	double cell_m = 1.0;
	double planar_spacing_m = 0.1;  ///< closer planar points are not kept
	double edge_spacing_m = 0.05;   ///< closer edge points are not kept
	int max_points_per_cell = 200;
	/** Planes from k nearest points need this spread (std along their second
	 * axis): a single ring's points are a line with no defined normal [m]. */
	double min_plane_spread_m = 0.03;
	/** Coarse plane voxels answer where the points hold no plane yet: at
	 * 10 m a VLP-16's rings are ~1 m apart on the ground, so fresh ground
	 * has a single ring near a point. 0 disables [m]. */
	double coarse_voxel_m = 2.0;
	int max_points_per_voxel = 800;
	int min_points_per_plane = 10;
	double radius_m = 60.0;  ///< cells farther from the sensor are dropped
	/** Stem model: an edge on a vertical line (and, with
	 * stem_model_planar, a planar point on a vertical surface) is matched
	 * to the circle (a vertical cylinder with a
	 * lean) fitted to the map's points around it, when that fits a stem:
	 * the residual is the distance to the stem's surface. A plane or line
	 * through the nearest map points lies on the part of the stem seen from
	 * earlier views (silhouettes move round a stem with the view). */
	bool stem_model = true;
	/** Planar matches go to the stem's circle too, not only edges. Off: a
	 * planar point on a stem keeps its plane. With range noise on the
	 * stems, the circle's planar rows shortened the forest-sim maps
	 * (doc/odometry.md, "Range noise on stems"). */
	bool stem_model_planar = false;
	double stem_fit_radius_m = 0.5;       ///< map points within (xy) [m]
	double stem_fit_half_height_m = 0.3;  ///< and within this in z [m]
	int stem_min_points = 12;             ///< inliers of the fit
	double stem_min_radius_m = 0.03;
	double stem_max_radius_m = 0.5;
	double stem_max_rmse_m = 0.03;  ///< robust RMSE of the fit [m]
	double stem_min_arc_deg = 60;   ///< arc the inliers cover [deg]

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& section) const override;
};

class LocalMap : public RegistrationTarget
{
   public:
	/** plane_flatness: the coarse voxels' plane test, fixed when they are
	 * fitted at insertion ([registration] plane_flatness). */
	explicit LocalMap(const LocalMapOptions& o = {},
	                  double plane_flatness = 0.1)
	    : o_(o), plane_flatness_(plane_flatness)
	{
	}

	/** Adds map-frame points. */
	void insert(const std::vector<Eigen::Vector3f>& edges,
	            const std::vector<Eigen::Vector3f>& planar);
	/** Drops voxels and cells farther than radius_m (xy) from `centre`. */
	void prune(const Eigen::Vector3d& centre);
	/** Moves the whole map rigidly (a loop correction of the map frame):
	 * points are moved and re-hashed, the coarse voxels rebuilt from them. */
	void transform(const Eigen::Isometry3d& T);
	void clear()
	{
		dropStemFits();
		planar_.clear();
		coarse_.clear();
		edges_.clear();
	}
	bool empty() const { return planar_.empty() && edges_.empty(); }
	size_t cells() const
	{
		return planar_.size() + coarse_.size() + edges_.size();
	}

	/** Heap bytes (estimate, core/memory.h). */
	size_t memoryBytes() const;

	bool matchPlane(const Eigen::Vector3f& x, double gate,
	                const RegistrationOptions& o, PlaneRow& out,
	                MatchReach& reach) const override;
	bool matchLine(const Eigen::Vector3f& x, double gate,
	               const RegistrationOptions& o, PlaneRow& a, PlaneRow& b,
	               MatchReach& reach) const override;

   private:
	using Key = uint64_t;
	static Key key(int64_t i, int64_t j, int64_t k)
	{
		// 21 bits per axis: +-1e6 cells, far beyond any stand.
		return core::packCellKey(i, j, k);
	}
	struct PlaneVoxel
	{
		Eigen::Vector3d origin;  ///< sums are taken relative to it (precision)
		Eigen::Vector3d sum = Eigen::Vector3d::Zero();
		Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
		int n = 0;
		int fitted_n = 0;  ///< n at the last refit
		// The plane, refitted by insert() whenever points were added, so the
		// queries only read (they run on several threads).
		bool planar = false;
		Eigen::Vector3d normal, mean;
	};
	/** A cell's points in blocks of four, x0..x3 y0..y3 z0..z3, so that a
	 * query or the spacing test compares four points per SSE instruction
	 * (the k-NN scan over the cells was a fifth of a mapping run's CPU).
	 * Unused lanes of the last block hold +inf: never near anything. */
	struct PointCell
	{
		std::vector<float> blocks;
		uint32_t n = 0;
		Eigen::Vector3f point(uint32_t i) const
		{
			const float* b = &blocks[(i / 4) * 12];
			const uint32_t l = i % 4;
			return {b[l], b[4 + l], b[8 + l]};
		}
		void push(const Eigen::Vector3f& p);
		/** Whether a point lies closer than sqrt(d2) to p. */
		bool anyWithin(const Eigen::Vector3f& p, float d2) const;
	};
	// Flat tables: a scan's registration queries and insertions are one
	// lookup per point, and std::unordered_map's node chasing was a sixth
	// of a mapping run's CPU.
	using PlaneGrid = core::FlatHashMap<PlaneVoxel>;
	using PointGrid = core::FlatHashMap<PointCell>;
	void addPoint(PointCell& c, float min_d2, const Eigen::Vector3f& p);
	static void prefetchPoints(const PointGrid& g, Key k);
	Key cellKey(const Eigen::Vector3f& p) const
	{
		const double s = o_.cell_m;
		return key(static_cast<int64_t>(std::floor(p.x() / s)),
		           static_cast<int64_t>(std::floor(p.y() / s)),
		           static_cast<int64_t>(std::floor(p.z() / s)));
	}
	/** Up to k nearest points of x within `extent`, nearest first. */
	void knn(const PointGrid& g, const Eigen::Vector3f& x, int k, double extent,
	         std::vector<std::pair<float, Eigen::Vector3f>>& best) const;
	/** The coarse plane nearest to x among its voxel and the six face
	 * neighbours. */
	bool coarsePlane(const Eigen::Vector3d& x, double gate, PlaneRow& out,
	                 MatchReach& reach) const;
	void refit(PlaneVoxel& v) const;
	/** A stem section fitted to the map's points around a small cell. */
	struct StemCell
	{
		bool ok = false;
		Eigen::Vector2d centre = Eigen::Vector2d::Zero();  ///< at height z0
		Eigen::Vector2d lean =
		    Eigen::Vector2d::Zero();  ///< centre shift / m up
		double r = 0;
		float z0 = 0;
	};
	/** Cells sharing one stem fit: small against a stem, so the fit around
	 * the cell's centre holds for every query in it [m]. */
	static constexpr double kStemCellM = 0.1, kStemCellHeightM = 0.2;
	StemCell fitStemAt(const Eigen::Vector3f& centre) const;
	/** The stem surface's tangent plane at x, if the map's points around x
	 * fit a stem (LocalMapOptions::stem_model). */
	bool stemRow(const Eigen::Vector3f& x, double gate, PlaneRow& out,
	             MatchReach& reach) const;
	/** Stem fits by cell, shared by the query threads and dropped whenever
	 * the map changes. One table for both threads, not one each: they ask
	 * for the same cells, and fitted them twice (with the fit's normal
	 * equations summed by hand, the handheld registration's median went
	 * from 11.1 to 8.0-8.7 ms). */
	struct StemCache
	{
		std::mutex mutex;
		core::FlatHashMap<StemCell> cells;
	};
	std::unique_ptr<StemCache> stems_ = std::make_unique<StemCache>();
	void dropStemFits()
	{
		std::lock_guard<std::mutex> lock(stems_->mutex);
		stems_->cells.clear();
	}
	LocalMapOptions o_;
	double plane_flatness_;
	PointGrid planar_, edges_;
	PlaneGrid coarse_;
};

}  // namespace forest_slam::odometry
