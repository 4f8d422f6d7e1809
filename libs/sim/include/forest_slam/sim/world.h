#pragma once
// The simulated scene: terrain plus analytic primitives (tapered elliptic stem
// segments, branch cylinders, see-through foliage volumes, boxes), indexed by
// a uniform 2D grid. A ray walks the grid cells it crosses (2D DDA), tests
// only the primitives registered in each cell whose height range it crosses,
// and stops as soon as the nearest hit lies inside the current cell; the
// terrain is then marched only up to that hit.
#include <forest_slam/sim/terrain.h>

#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <vector>

namespace forest_slam::sim
{
/** Ground-truth class of a return (the "gt_label" range layer). */
enum Label : uint8_t
{
	kLabelNone = 0,
	kLabelGround = 1,
	kLabelStem = 2,
	kLabelCrown = 3,  ///< branches and foliage
	kLabelShrub = 4,
	kLabelStructure = 5  ///< buildings, vehicles
};

struct Hit
{
	double t = std::numeric_limits<double>::infinity();
	uint8_t label = kLabelNone;
	uint16_t tree = 0;       ///< tree id + 1, 0 = none
	float reflectivity = 0;  ///< 0..100 diffuse, >100 retro-reflective
	float cos_incidence = 1;
	bool porous = false;  ///< a leaf inside a foliage volume (not solid)
	bool valid() const { return label != kLabelNone; }
};

/** A frustum of an elliptic cone along a (leaning) stem axis. */
struct StemSegment
{
	Eigen::Vector3d base;   ///< axis point at axial coordinate 0
	Eigen::Matrix3d R;      ///< columns: major axis, minor axis, stem axis
	double z0 = 0, z1 = 0;  ///< axial range
	double r0 = 0, r1 = 0;  ///< circle-equivalent radius at z0, z1
	double sa = 1, sb = 1;  ///< semi-axes are r*sa, r*sb
	double bark_amp = 0, bark_phase = 0;
	int bark_ridges = 7;
	uint16_t tree = 0;
	float reflectivity = 45;
	uint8_t label = kLabelStem;
};

struct Cylinder
{
	Eigen::Vector3d p0, axis;  ///< axis unit
	double length = 0, radius = 0;
	uint16_t tree = 0;
	float reflectivity = 40;
	uint8_t label = kLabelCrown;
};

/** Axis-aligned ellipsoid of foliage: a ray entering it travels an
 * exponentially distributed free path (extinction coefficient) before it
 * hits a leaf, so it may pass through: crowns and shrubs are see-through. */
struct Medium
{
	Eigen::Vector3d center, radii;
	double extinction_per_m = 1;
	uint16_t tree = 0;
	float reflectivity = 30;
	uint8_t label = kLabelCrown;
};

/** Box standing upright, rotated by yaw about z. */
struct Box
{
	Eigen::Vector3d center, half;
	double yaw = 0;
	float reflectivity = 70;
	uint8_t label = kLabelStructure;
};

/** Per-thread scratch for World::raycast (mailbox of tested primitives). */
struct RayScratch
{
	std::vector<uint32_t> mailbox;
	uint32_t stamp = 0;
};

class World
{
   public:
	World(std::unique_ptr<Terrain> terrain, double xmin, double ymin,
	      double xmax, double ymax);

	void add(const StemSegment& s) { stems_.push_back(s); }
	void add(const Cylinder& c) { cylinders_.push_back(c); }
	void add(const Medium& m) { media_.push_back(m); }
	void add(const Box& b) { boxes_.push_back(b); }
	/** Reflectivity of the ground at (x,y) (trail, yard, litter). */
	void setGroundReflectivity(std::function<float(double, double)> f)
	{
		ground_reflectivity_ = std::move(f);
	}
	/** Builds the acceleration grid; call after the last add(). */
	void finalize(double cell_m);

	/** Nearest hit with t in (t_min, t_max] along o + t d (|d| = 1).
	 * `ray_key` seeds the free paths through foliage, so the result depends
	 * only on the ray, never on thread or call order. */
	Hit raycast(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
	            double t_min, double t_max, uint64_t ray_key,
	            RayScratch& scratch, bool with_terrain = true) const;

	const Terrain& terrain() const { return *terrain_; }
	double xmin() const { return xmin_; }
	double ymin() const { return ymin_; }
	double xmax() const { return xmax_; }
	double ymax() const { return ymax_; }
	size_t primitiveCount() const
	{
		return stems_.size() + cylinders_.size() + media_.size() +
		       boxes_.size();
	}
	const std::vector<StemSegment>& stems() const { return stems_; }
	const std::vector<Cylinder>& cylinders() const { return cylinders_; }
	const std::vector<Medium>& media() const { return media_; }
	const std::vector<Box>& boxes() const { return boxes_; }

   private:
	struct Entry
	{
		float zmin, zmax;
		uint32_t id;  ///< global primitive index
	};
	int bandOf(double z) const
	{
		const int b =
		    static_cast<int>(std::floor((z - band_z0_) * inv_band_h_));
		return b < 0 ? 0 : (b >= n_bands_ ? n_bands_ - 1 : b);
	}
	void insert(uint32_t id, double xmin, double ymin, double xmax, double ymax,
	            double zmin, double zmax,
	            std::vector<std::vector<Entry>>& cells) const;
	void intersect(uint32_t id, const Eigen::Vector3d& o,
	               const Eigen::Vector3d& d, double t_min, uint64_t ray_key,
	               Hit& best) const;

	std::unique_ptr<Terrain> terrain_;
	double xmin_, ymin_, xmax_, ymax_;
	std::vector<StemSegment> stems_;
	std::vector<Cylinder> cylinders_;
	std::vector<Medium> media_;
	std::vector<Box> boxes_;
	std::function<float(double, double)> ground_reflectivity_;

	double cell_ = 2.0, inv_cell_ = 0.5;
	int nx_ = 0, ny_ = 0;
	/** Entries of a cell are split into height bands so that a ray, which
	 * crosses a cell within a narrow height range, reads few of them. */
	double band_z0_ = 0, band_h_ = 3.0, inv_band_h_ = 1.0 / 3.0;
	int n_bands_ = 1;
	std::vector<uint32_t> cell_start_;  ///< CSR offsets per (cell, band)
	std::vector<Entry> entries_;
	std::vector<float> cell_zmin_, cell_zmax_;  ///< height span per cell
	std::vector<float> cell_ground_min_;  ///< terrain lower bound per cell
	double zmax_all_ = -1e9;
	uint32_t off_cyl_ = 0, off_med_ = 0, off_box_ = 0, n_total_ = 0;
};

/** Intersections of a ray with single primitives (exposed for tests):
 * smallest t in (t_min, t_max) or false. */
bool intersectStem(const StemSegment& s, const Eigen::Vector3d& o,
                   const Eigen::Vector3d& d, double t_min, double t_max,
                   double& t, double& cos_inc);
bool intersectCylinder(const Cylinder& c, const Eigen::Vector3d& o,
                       const Eigen::Vector3d& d, double t_min, double t_max,
                       double& t, double& cos_inc);
/** Entry/exit of the ellipsoid clipped to t_min; false if missed. */
bool intersectEllipsoid(const Medium& m, const Eigen::Vector3d& o,
                        const Eigen::Vector3d& d, double t_min, double& t_in,
                        double& t_out);
bool intersectBox(const Box& b, const Eigen::Vector3d& o,
                  const Eigen::Vector3d& d, double t_min, double t_max,
                  double& t, double& cos_inc);

}  // namespace forest_slam::sim
