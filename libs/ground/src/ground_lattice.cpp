#include <forest_slam/core/config.h>
#include <forest_slam/core/fast_math.h>
#include <forest_slam/ground/ground_lattice.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <utility>

namespace forest_slam::ground
{
void GroundOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                       const std::string& s)
{
	FS_LOAD(c, s, node_spacing_m);
	FS_LOAD(c, s, radius_m);
	FS_LOAD(c, s, ground_threshold_m);
	FS_LOAD(c, s, lowest_band_m);
	FS_LOAD(c, s, max_slope_deg);
	FS_LOAD(c, s, max_step_m);
	FS_LOAD(c, s, max_rise_m);
	FS_LOAD(c, s, max_band_length_m);
	FS_LOAD(c, s, support_radius_m);
	FS_LOAD(c, s, seed_radius_m);
	FS_LOAD(c, s, seed_below_sensor_m);
	FS_LOAD(c, s, foot_radius_m);
	FS_LOAD(c, s, foot_gap_m);
	FS_LOAD(c, s, foot_reach_m);
	FS_LOAD(c, s, min_points_per_node);
	FS_LOAD(c, s, prior_variance_growth_m2);
	FS_LOAD(c, s, measurement_variance_floor_m2);
	const std::string where = core::configOrigin(c) + ": [" + s + "] ";
	if (!(node_spacing_m > 0.05 && node_spacing_m < 20))
		throw core::ConfigError(where + "node_spacing_m must be in (0.05, 20)");
	if (!(radius_m > node_spacing_m && radius_m / node_spacing_m <= 500))
		throw core::ConfigError(
		    where + "radius_m must exceed node_spacing_m (at most 500 nodes)");
	if (!(ground_threshold_m > 0) || !(lowest_band_m > 0) || !(max_step_m >= 0))
		throw core::ConfigError(
		    where +
		    "ground_threshold_m, lowest_band_m must be > 0, max_step_m >= 0");
	if (!(max_rise_m >= 0))
		throw core::ConfigError(where + "max_rise_m must be >= 0");
	if (!(max_band_length_m >= 0))
		throw core::ConfigError(where + "max_band_length_m must be >= 0");
	if (!(max_slope_deg > 0 && max_slope_deg < 80))
		throw core::ConfigError(where + "max_slope_deg must be in (0, 80)");
	if (!(support_radius_m >= node_spacing_m) ||
	    support_radius_m / node_spacing_m > 8)
		throw core::ConfigError(where +
		                        "support_radius_m must be in [node_spacing_m, "
		                        "8 node_spacing_m]");
	if (!(seed_radius_m >= 0) || !std::isfinite(seed_below_sensor_m))
		throw core::ConfigError(
		    where + "seed_radius_m must be >= 0, seed_below_sensor_m finite");
	if (!(foot_radius_m >= 0) || !(foot_gap_m > 0) ||
	    !(foot_reach_m > foot_gap_m))
		throw core::ConfigError(
		    where +
		    "foot_radius_m must be >= 0 (0: off), foot_gap_m "
		    "> 0, foot_reach_m > foot_gap_m");
	if (foot_radius_m > 0 && node_spacing_m / foot_radius_m > 100)
		throw core::ConfigError(
		    where + "foot_radius_m must be >= node_spacing_m / 100");
	if (min_points_per_node < 1)
		throw core::ConfigError(where + "min_points_per_node must be >= 1");
}

void GroundOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                     const std::string& s) const
{
	c.write(s, "node_spacing_m", node_spacing_m);
	c.write(s, "radius_m", radius_m);
	c.write(s, "ground_threshold_m", ground_threshold_m);
	c.write(s, "lowest_band_m", lowest_band_m);
	c.write(s, "max_slope_deg", max_slope_deg);
	c.write(s, "max_step_m", max_step_m);
	c.write(s, "max_rise_m", max_rise_m);
	c.write(s, "max_band_length_m", max_band_length_m);
	c.write(s, "support_radius_m", support_radius_m);
	c.write(s, "seed_radius_m", seed_radius_m);
	c.write(s, "seed_below_sensor_m", seed_below_sensor_m);
	c.write(s, "foot_radius_m", foot_radius_m);
	c.write(s, "foot_gap_m", foot_gap_m);
	c.write(s, "foot_reach_m", foot_reach_m);
	c.write(s, "min_points_per_node", min_points_per_node);
	c.write(s, "prior_variance_growth_m2", prior_variance_growth_m2);
	c.write(s, "measurement_variance_floor_m2", measurement_variance_floor_m2);
}

GroundLattice::GroundLattice(const GroundOptions& opts) : opts_(opts)
{
	// Window of nodes around the sensor's node, visited nearest first: the
	// ground grows outwards from the sensor.
	half_ =
	    static_cast<int>(std::ceil(opts_.radius_m / opts_.node_spacing_m)) + 1;
	for (int di = -half_; di <= half_; di++)
		for (int dj = -half_; dj <= half_; dj++)
			if (std::hypot(di, dj) <= half_) order_.push_back({di, dj});
	std::stable_sort(order_.begin(), order_.end(),
	                 [](const NodeKey& a, const NodeKey& b)
	                 { return a.i * a.i + a.j * a.j < b.i * b.i + b.j * b.j; });
}

namespace
{
/** Solves the symmetric 3x3 system A x = b by its adjugate (a fraction of
 * a pivoted decomposition's cost); false if A is singular. */
bool solveSym3(const Eigen::Matrix3d& A, const Eigen::Vector3d& b,
               Eigen::Vector3d& x)
{
	const double c00 = A(1, 1) * A(2, 2) - A(1, 2) * A(1, 2),
	             c01 = A(0, 2) * A(1, 2) - A(0, 1) * A(2, 2),
	             c02 = A(0, 1) * A(1, 2) - A(0, 2) * A(1, 1),
	             c11 = A(0, 0) * A(2, 2) - A(0, 2) * A(0, 2),
	             c12 = A(0, 2) * A(0, 1) - A(0, 0) * A(1, 2),
	             c22 = A(0, 0) * A(1, 1) - A(0, 1) * A(0, 1);
	const double det = A(0, 0) * c00 + A(0, 1) * c01 + A(0, 2) * c02;
	if (det == 0) return false;
	const double inv = 1.0 / det;
	x = Eigen::Vector3d(c00 * b[0] + c01 * b[1] + c02 * b[2],
	                    c01 * b[0] + c11 * b[1] + c12 * b[2],
	                    c02 * b[0] + c12 * b[1] + c22 * b[2]) *
	    inv;
	return true;
}

/** Node index of a coordinate in node units (core::floorToInt: no libm
 * call). */
inline int32_t floorToNode(double v)
{
	return static_cast<int32_t>(core::floorToInt(v));
}
}  // namespace

NodeKey GroundLattice::keyOf(double x, double y) const
{
	const double inv = 1.0 / opts_.node_spacing_m;
	return {floorToNode(x * inv + 0.5), floorToNode(y * inv + 0.5)};
}

const LatticeNode* NodeStore::find(const NodeKey& k) const
{
	const auto it = tiles_.find(tileKey(k));
	if (it == tiles_.end()) return nullptr;
	return &it->second[static_cast<size_t>(k.i & (kTile - 1)) * kTile +
	                   static_cast<size_t>(k.j & (kTile - 1))];
}
LatticeNode* NodeStore::find(const NodeKey& k)
{
	return const_cast<LatticeNode*>(std::as_const(*this).find(k));
}

NodeStore::Tile& NodeStore::tile(const NodeKey& k, size_t& slot)
{
	auto& t = tiles_[tileKey(k)];
	if (t.empty()) t.resize(static_cast<size_t>(kTile) * kTile);
	slot = static_cast<size_t>(k.i & (kTile - 1)) * kTile +
	       static_cast<size_t>(k.j & (kTile - 1));
	return t;
}

namespace
{
enum CellState : uint8_t
{
	kUnseen = 0,  ///< no (or too few) points this scan
	kPending,     ///< has points, not decided yet
	kAccepted,    ///< its level is ground
	kCapped,      ///< ground, but its level sits above the ground around it
	kRejected
};

/** Sums over a cell's ground candidates, coordinates relative to the cell
 * centre (x, y) and to the sensor height (z), for plane fits. */
struct Moments
{
	double n = 0, x = 0, y = 0, z = 0, xx = 0, xy = 0, yy = 0, xz = 0, yz = 0,
	       zz = 0;
	void add(double px, double py, double pz)
	{
		n++, x += px, y += py, z += pz;
		xx += px * px, xy += px * py, yy += py * py;
		xz += px * pz, yz += py * pz, zz += pz * pz;
	}
	/** Adds `o` whose coordinates are relative to a centre at (dx, dy) from
	 * ours. */
	void addShifted(const Moments& o, double dx, double dy)
	{
		n += o.n;
		x += o.x + o.n * dx, y += o.y + o.n * dy, z += o.z;
		xx += o.xx + 2 * dx * o.x + o.n * dx * dx;
		yy += o.yy + 2 * dy * o.y + o.n * dy * dy;
		xy += o.xy + dx * o.y + dy * o.x + o.n * dx * dy;
		xz += o.xz + dx * o.z, yz += o.yz + dy * o.z, zz += o.zz;
	}
};
}  // namespace

struct GroundLattice::Scratch
{
	std::vector<uint32_t> count, start, sorted;
	std::vector<float> zmin, level, pred;
	std::vector<uint8_t> state;
	std::vector<Moments> mom;
	std::vector<int32_t> cell_of;
	std::vector<float> band;
	std::vector<float> top;  ///< highest low return per foot cell of a node
	/** Foot cell of each point of a node (slot in `top`) and the steps to
	 * the neighbouring cells on its sides. */
	struct Foot
	{
		int slot, du, dv;
	};
	std::vector<Foot> foot;
	std::vector<uint8_t> lab;  ///< labels of a node's points, bit 1: foot?
	std::vector<Eigen::Vector3f> sp;  ///< the points in cell order
	std::vector<LatticeNode*> node;   ///< per cell; nullptr: no tile yet
	std::vector<float> prior_h, prior_sigma;  ///< confident priors, else NaN
	/** Support offered to the neighbours, or NaN (padded grid). */
	std::vector<float> sup;
	std::vector<ptrdiff_t> support_step;  ///< support offsets in `sup`
	std::vector<std::pair<double, double>> support_dxy;  ///< and in metres
};

GroundLattice::~GroundLattice() = default;
GroundLattice::GroundLattice(const GroundLattice& o)
    : opts_(o.opts_), nodes_(o.nodes_), half_(o.half_), order_(o.order_)
{
}
GroundLattice& GroundLattice::operator=(const GroundLattice& o)
{
	opts_ = o.opts_;
	nodes_ = o.nodes_;
	half_ = o.half_;
	order_ = o.order_;
	scratch_.reset();
	return *this;
}

std::vector<uint8_t> GroundLattice::labelScan(
    const std::vector<Eigen::Vector3f>& pts, const Eigen::Vector3d& sensor)
{
	if (!scratch_) scratch_ = std::make_unique<Scratch>();
	auto& S = *scratch_;
	const double s = opts_.node_spacing_m;
	const double r2 = opts_.radius_m * opts_.radius_m;
	const int H = half_, W = 2 * H + 1;
	const size_t ncell = static_cast<size_t>(W) * W;
	const NodeKey c0 = keyOf(sensor.x(), sensor.y());
	const double zs = sensor.z();
	auto cellIndex = [&](int di, int dj) { return (di + H) * W + (dj + H); };
	std::vector<uint8_t> labels(pts.size(), 0);

	// 1. Nearest node of every point (counting sort into a dense window);
	// the points are copied in cell order so that every later pass over a
	// cell reads contiguous memory.
	S.count.assign(ncell + 1, 0);
	S.cell_of.resize(pts.size());
	const double inv_s = 1.0 / s;
	for (uint32_t i = 0; i < pts.size(); i++)
	{
		const auto& p = pts[i];
		S.cell_of[i] = -1;
		const double dx = p.x() - sensor.x(), dy = p.y() - sensor.y();
		// (Written so that NaN and infinite coordinates fail it too.)
		if (!(dx * dx + dy * dy <= r2) || !std::isfinite(p.z())) continue;
		// Window indices 0..W-1 (unsigned: one comparison each).
		const uint32_t ui = floorToNode(p.x() * inv_s + 0.5) - c0.i + H,
		               uj = floorToNode(p.y() * inv_s + 0.5) - c0.j + H;
		if (ui >= static_cast<uint32_t>(W) || uj >= static_cast<uint32_t>(W))
			continue;
		const int32_t c = static_cast<int32_t>(ui * W + uj);
		S.cell_of[i] = c;
		S.count[c + 1]++;
	}
	for (size_t c = 0; c < ncell; c++) S.count[c + 1] += S.count[c];
	S.start.assign(S.count.begin(), S.count.end());  // start[c]..start[c+1]
	S.sorted.resize(S.count[ncell]);
	S.sp.resize(S.count[ncell]);
	S.zmin.assign(ncell, std::numeric_limits<float>::max());
	for (uint32_t i = 0; i < pts.size(); i++)
		if (const int32_t c = S.cell_of[i]; c >= 0)
		{
			const uint32_t k = S.count[c]++;
			S.sorted[k] = i;
			S.sp[k] = pts[i];
			S.zmin[c] = std::min(S.zmin[c], pts[i].z());
		}
	const Eigen::Vector3f* sp = S.sp.data();

	// 2. Level of each cell: median of its lowest band (robust to a single
	// low outlier and to grass).
	S.level.assign(ncell, 0.f);
	S.pred.assign(ncell, NAN);
	S.state.assign(ncell, kUnseen);
	S.band.resize(S.sp.size());
	for (size_t c = 0; c < ncell; c++)
	{
		const uint32_t b = S.start[c], e = S.start[c + 1];
		if (e - b < static_cast<uint32_t>(opts_.min_points_per_node)) continue;
		const float band_top =
		    S.zmin[c] + static_cast<float>(opts_.lowest_band_m);
		float* const band = S.band.data();
		size_t n = 0;
		for (uint32_t k = b; k < e; k++)  // branch-free
		{
			band[n] = sp[k].z();
			n += sp[k].z() <= band_top;
		}
		std::nth_element(band, band + n / 2, band + n);
		S.level[c] = band[n / 2];
		S.state[c] = kPending;
	}

	// Nodes of the window (a few tile look-ups) and their confident priors
	// (nodes estimated in earlier scans).
	S.node.assign(ncell, nullptr);
	S.prior_h.assign(ncell, NAN);
	S.prior_sigma.assign(ncell, NAN);
	for (int di = -H; di <= H; di++)
		for (int dj = -H; dj <= H;)
		{
			const NodeKey k0{c0.i + di, c0.j + dj};
			// The run of cells in this row that share k0's tile.
			const int run = std::min(
			    H - dj + 1, NodeStore::kTile - (k0.j & (NodeStore::kTile - 1)));
			if (LatticeNode* n = nodes_.find(k0))
			{
				for (int r = 0; r < run; r++, n++)
				{
					const size_t c = cellIndex(di, dj + r);
					S.node[c] = n;
					if (n->observations > 0 && n->var_h < kConfidentVariance)
					{
						S.prior_h[c] = static_cast<float>(n->h);
						S.prior_sigma[c] =
						    static_cast<float>(std::sqrt(n->var_h));
					}
				}
			}
			dj += run;
		}
	auto prior = [&](size_t c, float& h, float& sigma)
	{
		h = S.prior_h[c];
		sigma = S.prior_sigma[c];
		return std::isfinite(h);
	};

	// 3. Accept cell levels as ground, growing outwards from the sensor: a
	// level must agree with a plane through the ground already accepted
	// around it (this scan's accepted cells, or confident priors where this
	// scan sees nothing), fitted trimmed from above since shrubs, stems and
	// vehicles only ever raise a level. A cell with no such support may only
	// start the ground near the sensor and below it. Canopy layers, roofs
	// and shrub tops are thus cut off from the ground by their step.
	const double tan_slope = std::tan(opts_.max_slope_deg * M_PI / 180.0);
	// Offsets of the cells that may support a cell: the square of
	// support_radius_m around it (its corners matter where the rings are
	// sparse: the disk alone lost 11 % recall on the synthetic terrain).
	const int reach =
	    static_cast<int>(std::floor(opts_.support_radius_m / s + 1e-9));
	std::vector<NodeKey> support;
	for (int di = -reach; di <= reach; di++)
		for (int dj = -reach; dj <= reach; dj++)
			if (di || dj) support.push_back({di, dj});
	// What a cell offers its neighbours' support: its level once accepted
	// (or capped), its confident prior while unseen this scan, else NaN. On
	// a grid padded by `reach` NaN cells, so that the support of any window
	// cell is read without bounds checks.
	const int PW = W + 2 * reach;
	auto padIndex = [&](int di, int dj)
	{ return static_cast<size_t>(di + H + reach) * PW + (dj + H + reach); };
	S.sup.assign(static_cast<size_t>(PW) * PW, NAN);
	for (int di = -H; di <= H; di++)
		for (int dj = -H; dj <= H; dj++)
		{
			const size_t c = cellIndex(di, dj);
			if (S.state[c] == kUnseen) S.sup[padIndex(di, dj)] = S.prior_h[c];
		}
	S.support_step.clear();
	S.support_dxy.clear();
	for (const auto& o : support)
	{
		S.support_step.push_back(o.i * PW + o.j);
		S.support_dxy.push_back({o.i * s, o.j * s});
	}
	struct Level
	{
		double dx, dy, z;
		bool used;
	};
	std::vector<Level> around;
	// The levels around the cell being decided: the support (at most
	// support.size()), then for a bridge the pending levels around it.
	// (Offsets as indices into `support`.)
	struct Near
	{
		float z;
		uint16_t k;
		bool used;
	};
	std::vector<Near> near(2 * support.size());
	size_t n_near = 0;
	// Trimmed plane through the used levels lv[0, nl): fitted, levels more
	// than max_step above it dropped (dropped ones back in if they fit
	// again), refitted. Returns the number of levels it rests on; sol[0] is
	// the prediction at (0, 0). The normal equations are kept as sums that
	// follow the trimming.
	auto trimmedPlane =
	    [&](Near* const lv, const size_t nl, Eigen::Vector3d& sol)
	{
		Near* const lv_end = lv + nl;
		const auto* const dxy = S.support_dxy.data();
		double n = 0, x = 0, y = 0, xx = 0, xy = 0, yy = 0, z = 0, xz = 0,
		       yz = 0;
		auto add = [&](const Near& l, double w)
		{
			const double dx = dxy[l.k].first, dy = dxy[l.k].second, lz = l.z;
			n += w, x += w * dx, y += w * dy, z += w * lz;
			xx += w * dx * dx, xy += w * dx * dy, yy += w * dy * dy;
			xz += w * dx * lz, yz += w * dy * lz;
		};
		int used = 0;
		for (const Near* l = lv; l != lv_end; l++)
			if (l->used) add(*l, 1), used++;
		sol = Eigen::Vector3d::Zero();
		for (int iter = 0; iter < 4; iter++)
		{
			if (used == 0) return 0;
			// Weak ridge on the slopes: a line of support (one radial ray)
			// does not decide the slope across it.
			Eigen::Matrix3d A;
			A << n + 1e-6, x, y, x, xx + s * s, xy, y, xy, yy + s * s;
			solveSym3(A, Eigen::Vector3d(z, xz, yz), sol);
			bool changed = false;
			for (Near* pl = lv; pl != lv_end; pl++)
			{
				Near& l = *pl;
				const bool keep = l.z - (sol[0] + sol[1] * dxy[l.k].first +
				                         sol[2] * dxy[l.k].second) <=
				                  opts_.max_step_m;
				if (keep == l.used) continue;
				changed = true;
				add(l, keep ? 1 : -1);
				used += keep ? 1 : -1;
				l.used = keep;
			}
			if (!changed) return used;
		}
		return static_cast<int>(nl);
	};
	// Seed plane: the lower envelope of the levels near the sensor (a plane
	// refitted to the levels within max_step above it, starting low), so
	// that roofs, shrubs and crowns near the sensor never start the ground.
	const double seed_r2 = opts_.seed_radius_m * opts_.seed_radius_m;
	Eigen::Vector3d seed(0, 0, 0);
	bool seed_ok = false;
	{
		around.clear();
		for (const auto& off : order_)
		{
			const double dx = (c0.i + off.i) * s - sensor.x(),
			             dy = (c0.j + off.j) * s - sensor.y();
			if (dx * dx + dy * dy > seed_r2) break;
			const size_t c = cellIndex(off.i, off.j);
			if (S.state[c] == kPending &&
			    S.level[c] <= zs - opts_.seed_below_sensor_m)
				around.push_back({dx, dy, S.level[c], true});
		}
		if (around.size() >= 3)
		{
			std::vector<double> z;
			for (const auto& l : around) z.push_back(l.z);
			std::nth_element(z.begin(), z.begin() + z.size() / 5, z.end());
			seed = Eigen::Vector3d(z[z.size() / 5], 0, 0);
			for (int iter = 0; iter < 8; iter++)
			{
				Eigen::Matrix3d A =
				    Eigen::Vector3d(1e-6, 1.0, 1.0).asDiagonal();
				Eigen::Vector3d b = Eigen::Vector3d::Zero();
				int n = 0;
				for (const auto& l : around)
					if (l.z - (seed[0] + seed[1] * l.dx + seed[2] * l.dy) <=
					    opts_.max_step_m)
					{
						const Eigen::Vector3d row(1, l.dx, l.dy);
						A += row * row.transpose();
						b += row * l.z;
						n++;
					}
				if (n < 3) break;
				seed = A.ldlt().solve(b);
				seed_ok = std::hypot(seed[1], seed[2]) <= tan_slope;
			}
		}
	}
	// Nearest-so-far accepted ground per azimuth sector (cells are visited
	// nearest first).
	constexpr int kSectors = 720;
	std::vector<float> sector_z(kSectors, NAN), sector_d(kSectors, NAN);
	for (const auto& off : order_)
	{
		const size_t c = cellIndex(off.i, off.j);
		if (S.state[c] != kPending) continue;
		const double level = S.level[c];
		float ph, psig;
		const bool has_prior = prior(c, ph, psig);
		if (has_prior && level - ph > opts_.max_step_m + 3 * psig)
		{
			S.state[c] = kRejected;  // well above ground seen before
			S.pred[c] = ph;
			continue;
		}
		n_near = 0;
		bool seeded_only = true;
		const float* const sup_c = &S.sup[padIndex(off.i, off.j)];
		for (size_t k = 0; k < S.support_step.size(); k++)
		{
			// Branch-free: which neighbours have ground is unpredictable.
			const float v = sup_c[S.support_step[k]];
			near[n_near] = {v, static_cast<uint16_t>(k), true};
			n_near += !std::isnan(v);
		}
		bool ok = false;
		Eigen::Vector3d sol;
		if (n_near >= 3 && trimmedPlane(near.data(), n_near, sol) >= 3)
		{
			seeded_only = false;
			S.pred[c] = static_cast<float>(sol[0]);
			ok =
			    level - sol[0] <= opts_.max_step_m &&
			    std::sqrt(sol[1] * sol[1] + sol[2] * sol[2]) <= tan_slope + 0.2;
		}
		else if (has_prior)
		{
			seeded_only = false;
			S.pred[c] = ph;
			ok = true;  // within the prior (checked above)
		}
		const double dx = (c0.i + off.i) * s - sensor.x(),
		             dy = (c0.j + off.j) * s - sensor.y();
		const double d = std::sqrt(dx * dx + dy * dy);
		// (Only for cells that bridge or are accepted.)
		auto sectorOf = [&]
		{
			return static_cast<int>((std::atan2(dy, dx) + M_PI) / (2 * M_PI) *
			                        kSectors) %
			       kSectors;
		};
		if (seeded_only && d <= opts_.seed_radius_m)
			ok = seed_ok && level <= zs - opts_.seed_below_sensor_m &&
			     level - (seed[0] + seed[1] * dx + seed[2] * dy) <=
			         opts_.max_step_m;
		else if (seeded_only && level <= zs - opts_.seed_below_sensor_m)
		{
			// Far from the sensor the rings hit the ground metres apart, so
			// a ring may have no accepted ground near it: bridge the gap
			// from the nearest accepted ground in the same direction (at most
			// the steepest slope between them), if the level also agrees with
			// the levels around it. Only below the sensor: canopy seen by
			// the upward beams never bridges.
			int from = -1;
			const int bin = sectorOf();
			for (int k = bin - 1; k <= bin + 1; k++)
			{
				const int b = (k + kSectors) % kSectors;
				if (std::isfinite(sector_d[b]) &&
				    (from < 0 || sector_d[b] > sector_d[from]))
					from = b;
			}
			if (from >= 0 &&
			    level - sector_z[from] <=
			        opts_.max_step_m + tan_slope * (d - sector_d[from]))
			{
				for (size_t k = 0; k < support.size(); k++)
				{
					const int ni = off.i + support[k].i,
					          nj = off.j + support[k].j;
					if (std::abs(ni) > H || std::abs(nj) > H) continue;
					const size_t nb = cellIndex(ni, nj);
					if (S.state[nb] != kUnseen && S.state[nb] != kAccepted)
						near[n_near++] = {S.level[nb], static_cast<uint16_t>(k),
						                  true};
				}
				ok = true;
				if (n_near >= 4 && trimmedPlane(near.data(), n_near, sol) >= 3)
					ok = level - sol[0] <= opts_.max_step_m;
			}
		}
		S.state[c] = ok ? kAccepted : kRejected;
		// A level accepted but above the ground predicted around it is
		// mostly what covers the ground (the low foliage of a shrub): the
		// node is measured at the prediction + max_rise_m, not at it.
		if (ok && std::isfinite(S.pred[c]) &&
		    level > S.pred[c] + opts_.max_rise_m)
		{
			S.state[c] = kCapped;
			S.level[c] = static_cast<float>(S.pred[c] + opts_.max_rise_m);
		}
		if (ok)
		{
			S.sup[padIndex(off.i, off.j)] = S.level[c];
			const int bin = sectorOf();
			sector_z[bin] = static_cast<float>(level);
			sector_d[bin] = static_cast<float>(d);
		}
	}

	// 4. Local plane per accepted node from the ground candidates of the
	// accepted cells around it, fused with the node's prior (Kalman-style).
	// (Independent per cell: memory order.) The moments of the ground
	// candidates (up to level + ground threshold) of the accepted cells
	// first, the only ones the plane fits read.
	S.mom.resize(ncell);
	for (size_t c = 0; c < ncell; c++)
	{
		if (S.state[c] != kAccepted) continue;
		S.mom[c] = Moments();
		const int di = static_cast<int>(c / W) - H,
		          dj = static_cast<int>(c % W) - H;
		const double xc = (c0.i + di) * s, yc = (c0.j + dj) * s;
		const float top =
		    S.level[c] + static_cast<float>(opts_.ground_threshold_m);
		for (uint32_t k = S.start[c]; k < S.start[c + 1]; k++)
		{
			const auto& p = sp[k];
			if (p.z() <= top) S.mom[c].add(p.x() - xc, p.y() - yc, p.z() - zs);
		}
	}
	for (size_t c = 0; c < ncell; c++)
	{
		if (S.state[c] == kUnseen) continue;
		const NodeKey off{static_cast<int32_t>(c / W) - H,
		                  static_cast<int32_t>(c % W) - H};
		if (!S.node[c]) S.node[c] = &nodes_.at({c0.i + off.i, c0.j + off.j});
		auto& node = *S.node[c];
		node.var_h += opts_.prior_variance_growth_m2;
		if (S.state[c] == kCapped)
		{
			// Raised by what covers the ground: measured as the level the
			// ground around predicts, with the variance of max_rise_m.
			const double var_m = std::max(opts_.measurement_variance_floor_m2,
			                              opts_.max_rise_m * opts_.max_rise_m);
			const double w = node.var_h / (node.var_h + var_m);
			node.h += w * (S.level[c] - node.h);
			node.var_h = node.var_h * var_m / (node.var_h + var_m);
			node.observations++;
			nodes_.markMeasured();
			continue;
		}
		if (S.state[c] != kAccepted) continue;
		Moments m = S.mom[c];
		for (int di = -1; di <= 1; di++)
			for (int dj = -1; dj <= 1; dj++)
			{
				const int ni = off.i + di, nj = off.j + dj;
				if ((!di && !dj) || std::abs(ni) > H || std::abs(nj) > H)
					continue;
				const size_t nb = cellIndex(ni, nj);
				if (S.state[nb] == kAccepted)
					m.addShifted(S.mom[nb], di * s, dj * s);
			}
		if (m.n < opts_.min_points_per_node) continue;
		Eigen::Matrix3d A;
		A << m.n, m.x, m.y, m.x, m.xx, m.xy, m.y, m.xy, m.yy;
		const Eigen::Vector3d b(m.z, m.xz, m.yz);
		Eigen::Vector3d sol;
		bool plane = A.determinant() > 1e-6 * m.n * m.n;
		if (plane)
		{
			plane = solveSym3(A, b, sol) && sol.allFinite() &&
			        std::sqrt(sol[1] * sol[1] + sol[2] * sol[2]) <= tan_slope;
		}
		if (!plane) sol = Eigen::Vector3d(S.level[c] - zs, node.sx, node.sy);
		// Residual spread of the cell's own candidates about the plane.
		const Moments& o = S.mom[c];
		const double a0 = sol[0], a1 = sol[1], a2 = sol[2];
		const double ss = o.zz - 2 * (a0 * o.z + a1 * o.xz + a2 * o.yz) +
		                  a0 * a0 * o.n + a1 * a1 * o.xx + a2 * a2 * o.yy +
		                  2 * (a0 * a1 * o.x + a0 * a2 * o.y + a1 * a2 * o.xy);
		const double var_m = std::max(opts_.measurement_variance_floor_m2,
		                              std::max(0.0, ss) / std::max(1.0, o.n));
		const double h = sol[0] + zs;
		const double w = node.var_h / (node.var_h + var_m);
		node.h += w * (h - node.h);
		node.sx += w * (sol[1] - node.sx);
		node.sy += w * (sol[2] - node.sy);
		node.var_h = node.var_h * var_m / (node.var_h + var_m);
		node.observations++;
		nodes_.markMeasured();
	}

	// 5. Labels: height above the node's plane; where the node was never
	// measured, above the level its accepted neighbours predict. A low point
	// with another return straight above it (foot_gap_m..foot_reach_m
	// higher, within foot_radius_m horizontally) is the foot of a stem, wall
	// or shrub, not ground: seen from the side, the rings above hit the same
	// vertical surface at the same place, while above ground there is air.
	// Grazing beams: the band of a point at horizontal distance d is at most
	// max_band_length_m long along its beam, i.e. at most
	// max_band_length_m * tan(incidence) thick, the incidence on a plane
	// through the ground under the sensor being atan(sensor height / d).
	// (The sensor's own height, not the point's depth below it: on a
	// uniform slope that is the exact incidence, and node slopes far out,
	// fitted to one ring, are too noisy to tilt the beam by.)
	// Ground under the sensor: the lattice's, else this scan's seed plane.
	double band_k = 0;
	if (opts_.max_band_length_m > 0)
	{
		double z_under = NAN;
		if (!heightAt(sensor.x(), sensor.y(), z_under) && seed_ok)
			z_under = seed[0];
		if (zs > z_under) band_k = opts_.max_band_length_m * (zs - z_under);
	}
	const double fc = opts_.foot_radius_m;
	S.top.clear();
	const int L = fc > 0 ? static_cast<int>(std::ceil(s / fc)) + 2 : 0;
	const double inv_fc = fc > 0 ? 1.0 / fc : 0.0;
	const double thr = opts_.ground_threshold_m, band_k2 = band_k * band_k;
	S.lab.resize(S.sp.size());
	for (size_t c = 0; c < ncell; c++)  // memory order: sp is read in turn
	{
		const uint32_t b = S.start[c], e = S.start[c + 1];
		if (b == e) continue;
		const NodeKey off{static_cast<int32_t>(c / W) - H,
		                  static_cast<int32_t>(c % W) - H};
		const NodeKey key{c0.i + off.i, c0.j + off.j};
		const double xc = key.i * s, yc = key.j * s;
		const LatticeNode* node =
		    S.node[c] && S.node[c]->observations > 0 ? S.node[c] : nullptr;
		if (!node && !std::isfinite(S.pred[c])) continue;
		// Two passes over the node's points: labels by height (and whether
		// the foot check applies); then, if it applies to any, the highest
		// low return per foot cell of this node (a foot and the surface
		// above it are in the same node but at its border) and the check.
		// Branch-free where the outcome is data-dependent.
		bool any_foot = false;
		float cap = 0, foot_zmin = INFINITY;
		for (uint32_t k = b; k < e; k++)
		{
			const auto& p = sp[k];
			const double ground_z = node ? node->h + node->sx * (p.x() - xc) +
			                                   node->sy * (p.y() - yc)
			                             : S.pred[c];
			const double dz = p.z() - ground_z;
			// dz < min(threshold, band_k / horizontal distance), without
			// the square root.
			uint8_t lab = dz < thr;
			if (band_k > 0)
			{
				const double bx = p.x() - sensor.x(), by = p.y() - sensor.y();
				lab &= !(dz > 0) | (dz * dz * (bx * bx + by * by) < band_k2);
			}
			// Below the plane a point is ground even under foliage (ground
			// seen through a shrub); above it, a foot is not: bit 1.
			const uint8_t foot = lab & (dz >= 0) & (L > 0);
			if (foot && !any_foot)
			{
				any_foot = true;
				cap = static_cast<float>(ground_z + opts_.foot_reach_m);
			}
			foot_zmin = std::min(foot_zmin, foot ? p.z() : INFINITY);
			S.lab[k - b] = static_cast<uint8_t>(lab | foot << 1);
		}
		if (any_foot)
		{
			// No return foot_gap_m above the lowest point checked (and below
			// the cap): no foot in this node.
			float low_top = -INFINITY;
			for (uint32_t k = b; k < e; k++)
				low_top =
				    std::max(low_top, sp[k].z() <= cap ? sp[k].z() : -INFINITY);
			any_foot =
			    low_top > foot_zmin + static_cast<float>(opts_.foot_gap_m);
		}
		if (any_foot)
		{
			// Foot cells (u, v) in [0, L) on a grid padded by one cell of
			// -inf: the point's cell, the neighbours on the sides of it the
			// point is nearest to.
			const int P = L + 2;
			const double gx0 = xc - 0.5 * s - fc, gy0 = yc - 0.5 * s - fc;
			// (All -inf between nodes: reset through the points' slots.)
			if (S.top.size() != static_cast<size_t>(P) * P)
				S.top.assign(static_cast<size_t>(P) * P, -INFINITY);
			S.foot.resize(e - b);
			for (uint32_t k = b; k < e; k++)
			{
				const auto& p = sp[k];
				const double fu = (p.x() - gx0) * inv_fc,
				             fv = (p.y() - gy0) * inv_fc;
				const int u = std::clamp(static_cast<int>(fu), 0, L - 1),
				          v = std::clamp(static_cast<int>(fv), 0, L - 1);
				const int slot = (u + 1) * P + v + 1;
				S.foot[k - b] = {slot, fu - u < 0.5 ? -P : P,
				                 fv - v < 0.5 ? -1 : 1};
				float& t = S.top[slot];
				t = std::max(t, p.z() <= cap ? p.z() : -INFINITY);
			}
			const float gap = static_cast<float>(opts_.foot_gap_m);
			const float* const top = S.top.data();
			for (uint32_t k = b; k < e; k++)
			{
				const auto& f = S.foot[k - b];
				const float t = std::max(
				    std::max(top[f.slot], top[f.slot + f.dv]),
				    std::max(top[f.slot + f.du], top[f.slot + f.du + f.dv]));
				const uint8_t l = S.lab[k - b];
				labels[S.sorted[k]] =
				    (l & 1) & !((l >> 1) & (t > sp[k].z() + gap));
			}
			for (uint32_t k = b; k < e; k++)
				S.top[S.foot[k - b].slot] = -INFINITY;
		}
		else
			for (uint32_t k = b; k < e; k++)
				labels[S.sorted[k]] = S.lab[k - b] & 1;
	}
	return labels;
}
bool GroundLattice::heightAt(double x, double y, double& z) const
{
	const double s = opts_.node_spacing_m;
	const double fx = x / s, fy = y / s;
	const int i0 = static_cast<int>(std::floor(fx)),
	          j0 = static_cast<int>(std::floor(fy));
	double wsum = 0, zsum = 0;
	for (int di = 0; di <= 1; di++)
		for (int dj = 0; dj <= 1; dj++)
		{
			const LatticeNode* nd = nodes_.find({i0 + di, j0 + dj});
			if (!nd || nd->observations == 0) continue;
			const double w =
			    (di ? fx - i0 : 1 - (fx - i0)) * (dj ? fy - j0 : 1 - (fy - j0));
			const auto& n = *nd;
			// Each node predicts with its own plane; blend bilinearly.
			const double zn =
			    n.h + n.sx * (x - (i0 + di) * s) + n.sy * (y - (j0 + dj) * s);
			zsum += (w + 1e-9) * zn;
			wsum += w + 1e-9;
		}
	if (wsum <= 0) return false;
	z = zsum / wsum;
	return true;
}

}  // namespace forest_slam::ground
