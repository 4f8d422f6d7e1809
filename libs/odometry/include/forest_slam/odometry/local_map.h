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
#include <forest_slam/odometry/feature_registration.h>

#include <cmath>
#include <cstdint>
#include <unordered_map>
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
	                const RegistrationOptions& o, PlaneRow& out) const override;
	bool matchLine(const Eigen::Vector3f& x, double gate,
	               const RegistrationOptions& o, PlaneRow& a,
	               PlaneRow& b) const override;

   private:
	using Key = uint64_t;
	static Key key(int64_t i, int64_t j, int64_t k)
	{
		// 21 bits per axis: +-1e6 cells, far beyond any stand.
		const uint64_t m = (1u << 21) - 1;
		return ((static_cast<uint64_t>(i) & m) << 42) |
		       ((static_cast<uint64_t>(j) & m) << 21) |
		       (static_cast<uint64_t>(k) & m);
	}
	struct KeyHash
	{
		size_t operator()(Key k) const
		{
			return static_cast<size_t>((k * 0x9E3779B97F4A7C15ull) >> 17);
		}
	};
	struct PlaneVoxel
	{
		Eigen::Vector3d origin;  ///< sums are taken relative to it (precision)
		Eigen::Vector3d sum = Eigen::Vector3d::Zero();
		Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
		int n = 0;
		// The plane, refitted by insert() whenever points were added, so the
		// queries only read (they run on several threads).
		bool planar = false;
		bool touched = false;  ///< points added during the current insert()
		Eigen::Vector3d normal, mean;
	};
	struct PointCell
	{
		std::vector<Eigen::Vector3f> pts;
	};
	using PlaneGrid = std::unordered_map<Key, PlaneVoxel, KeyHash>;
	using PointGrid = std::unordered_map<Key, PointCell, KeyHash>;
	/** The cells an insert() touched last, by key: a scan's consecutive
	 * points (a firing column, then the next one) fall into the same few
	 * cells, and the hash lookups were most of the insertion time.
	 * unordered_map elements keep their address until erased, and insert()
	 * never erases. */
	template <class Grid>
	class CellCache
	{
	   public:
		typename Grid::mapped_type& get(Grid& g, Key k, bool* fresh = nullptr)
		{
			auto& e = slots_[KeyHash()(k) & (kSlots - 1)];
			if (e.first == k)
			{
				if (fresh) *fresh = false;
				return *e.second;
			}
			auto [it, added] = g.try_emplace(k);
			if (fresh) *fresh = added;
			e = {k, &it->second};
			return it->second;
		}

	   private:
		static constexpr size_t kSlots = 256;
		// ~0 is no key: key() uses the low 63 bits only.
		std::pair<Key, typename Grid::mapped_type*> slots_[kSlots];

	   public:
		CellCache()
		{
			for (auto& e : slots_) e = {~Key(0), nullptr};
		}
	};
	void addPoint(PointCell& c, float min_d2, const Eigen::Vector3f& p);
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
	bool coarsePlane(const Eigen::Vector3d& x, double gate,
	                 PlaneRow& out) const;
	void refit(PlaneVoxel& v) const;

	LocalMapOptions o_;
	double plane_flatness_;
	PointGrid planar_, edges_;
	PlaneGrid coarse_;
};

}  // namespace forest_slam::odometry
