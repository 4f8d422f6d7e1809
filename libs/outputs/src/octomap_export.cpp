#include <forest_slam/core/atomic_file.h>
#include <forest_slam/core/flat_hash_map.h>
#include <forest_slam/outputs/octomap_export.h>

#include <octomap/ColorOcTree.h>
#include <octomap/OcTree.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <future>
#include <memory>
#include <stdexcept>
#include <unordered_map>
#include <vector>

namespace forest_slam::outputs
{
namespace
{
/** Blue (low) -> green -> red (high). */
void heightColour(double f, uint8_t& r, uint8_t& g, uint8_t& b)
{
	f = std::clamp(f, 0.0, 1.0);
	r = static_cast<uint8_t>(255 * std::clamp(2 * f - 1, 0.0, 1.0));
	b = static_cast<uint8_t>(255 * std::clamp(1 - 2 * f, 0.0, 1.0));
	g = static_cast<uint8_t>(255 - r - b);
}

void writeColourTree(const octomap::OcTree& tree, const std::string& path)
{
	double zmin = 1e300, zmax = -1e300;
	for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
		if (tree.isNodeOccupied(*it))
		{
			zmin = std::min(zmin, it.getZ());
			zmax = std::max(zmax, it.getZ());
		}
	octomap::ColorOcTree colour(tree.getResolution());
	const double res = tree.getResolution();
	for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
	{
		if (!tree.isNodeOccupied(*it)) continue;
		// A pruned leaf covers (size/res)^3 voxels of the finest level.
		const int n =
		    std::max(1, static_cast<int>(std::lround(it.getSize() / res)));
		const double half = it.getSize() / 2 - res / 2;
		for (int i = 0; i < n; i++)
			for (int j = 0; j < n; j++)
				for (int k = 0; k < n; k++)
				{
					const octomap::point3d p(it.getX() - half + i * res,
					                         it.getY() - half + j * res,
					                         it.getZ() - half + k * res);
					auto* node = colour.updateNode(p, it->getLogOdds());
					uint8_t r, g, b;
					heightColour((p.z() - zmin) / std::max(1e-6, zmax - zmin),
					             r, g, b);
					node->setColor(r, g, b);
				}
	}
	colour.updateInnerOccupancy();
	if (!colour.write(core::tempPathFor(path)))
		throw std::runtime_error("cannot write OctoMap '" + path + "'");
	core::commitTempFile(path);
}
}  // namespace

OctomapSummary writeOctomap(const Keyframes& keyframes, double resolution_m,
                            double max_range_m, const std::string& bt_path,
                            const std::string& ot_path,
                            double keyframe_spacing_m)
{
	return writeOctomap(
	    keyframes, [&](size_t i) { return keyframes[i].points; }, resolution_m,
	    max_range_m, bt_path, ot_path, keyframe_spacing_m);
}

namespace
{
/** The keyframes to cast, in order: each farther than `spacing_m` from
 * every one kept before it (a grid of spacing_m cells, 27 looked up). */
std::vector<size_t> spacedKeyframes(const Keyframes& keyframes,
                                    double spacing_m)
{
	std::vector<size_t> keep;
	std::unordered_map<uint64_t, std::vector<Eigen::Vector3d>> grid;
	auto cell = [&](const Eigen::Vector3d& p, int dx, int dy, int dz)
	{
		auto axis = [&](double v, int d)
		{ return uint64_t(int64_t(std::floor(v / spacing_m)) + d) & 0x1fffff; };
		return (axis(p.x(), dx) << 42) | (axis(p.y(), dy) << 21) |
		       axis(p.z(), dz);
	};
	for (size_t i = 0; i < keyframes.size(); i++)
	{
		const Eigen::Vector3d p = keyframes[i].sensor_pose.translation();
		bool near = false;
		for (int dx = -1; dx <= 1 && !near && spacing_m > 0; dx++)
			for (int dy = -1; dy <= 1 && !near; dy++)
				for (int dz = -1; dz <= 1 && !near; dz++)
				{
					const auto it = grid.find(cell(p, dx, dy, dz));
					if (it == grid.end()) continue;
					for (const auto& q : it->second)
						if ((q - p).norm() < spacing_m) near = true;
				}
		if (near) continue;
		keep.push_back(i);
		if (spacing_m > 0) grid[cell(p, 0, 0, 0)].push_back(p);
	}
	return keep;
}

/** A key's Morton code, the bits of k[0], k[1], k[2] interleaved from the
 * most significant down: the depth-first order of the tree. Updating a
 * keyframe's few hundred thousand free keys in hash order descended the 16
 * levels of a tree of millions of leaves at random: most of the export.
 * Each key's log-odds does not depend on the order of the other keys. */
inline uint64_t spreadBits(uint64_t x)
{
	// Bit b of a 16-bit value to bit 3b.
	x &= 0xffff;
	x = (x | x << 16) & 0x0000ff0000ffull;
	x = (x | x << 8) & 0x00f00f00f00full;
	x = (x | x << 4) & 0x0c30c30c30c3ull;
	x = (x | x << 2) & 0x249249249249ull;
	return x;
}
inline uint64_t compactBits(uint64_t x)
{
	x &= 0x249249249249ull;
	x = (x | x >> 2) & 0x0c30c30c30c3ull;
	x = (x | x >> 4) & 0x00f00f00f00full;
	x = (x | x >> 8) & 0x0000ff0000ffull;
	x = (x | x >> 16) & 0xffff;
	return x;
}
inline uint64_t morton(const octomap::OcTreeKey& k)
{
	return spreadBits(k[0]) << 2 | spreadBits(k[1]) << 1 | spreadBits(k[2]);
}
inline octomap::OcTreeKey fromMorton(uint64_t m)
{
	return octomap::OcTreeKey(
	    static_cast<octomap::key_type>(compactBits(m >> 2)),
	    static_cast<octomap::key_type>(compactBits(m >> 1)),
	    static_cast<octomap::key_type>(compactBits(m)));
}

/** octomap's child index (computeChildIdx: x bit 0, y bit 1, z bit 2) at
 * tree level d (0: the root's children) of a key given by its Morton code
 * (x, y, z bits of level b at code bits 3b + 2, 3b + 1, 3b). */
inline unsigned childIdx(uint64_t code, unsigned depth, unsigned d)
{
	const unsigned t = unsigned(code >> (3 * (depth - 1 - d))) & 7u;
	return ((t >> 2) & 1u) | (t & 2u) | ((t & 1u) << 2);
}

/** tree.updateNode(k, occupied, lazy_eval = true) for every key (sorted
 * Morton codes), in tree order: the path of the previous key is kept and
 * only the levels below the first child index that differs are descended
 * (16 levels from the root per key was most of the updates' time); that
 * level is the codes' common prefix (leading zeros of their xor) in
 * three-bit steps. Same nodes, same log-odds: with lazy evaluation
 * nothing is pruned, so no node has to be expanded, and updateNodeLogOdds
 * clamps as updateNode's early exit skips. */
void updateInTreeOrder(octomap::OcTree& tree,
                       const std::vector<uint64_t>& codes, bool occupied)
{
	if (codes.empty()) return;
	size_t first = 0;
	if (!tree.getRoot())
		tree.updateNode(fromMorton(codes[first++]), occupied, true);
	const float update =
	    occupied ? tree.getProbHitLog() : tree.getProbMissLog();
	const unsigned depth = tree.getTreeDepth();
	std::vector<octomap::OcTreeNode*> path(depth + 1, nullptr);
	path[0] = tree.getRoot();
	unsigned valid = 0;  // path[0..valid] lie on the previous key's path
	uint64_t prev = 0;
	for (size_t i = first; i < codes.size(); i++)
	{
		const uint64_t c = codes[i];
		unsigned d = 0;
		if (valid > 0)
		{
			// Levels whose 3 bits agree, from the top of the 3 * depth
			// bits (equal codes: all of them).
			const uint64_t x = c ^ prev;
			const unsigned same =
			    x == 0 ? depth
			           : (unsigned(__builtin_clzll(x)) - (64 - 3 * depth)) / 3;
			d = std::min(valid, same);
		}
		for (; d < depth; d++)
		{
			const unsigned pos = childIdx(c, depth, d);
			path[d + 1] = tree.nodeChildExists(path[d], pos)
			                  ? tree.getNodeChild(path[d], pos)
			                  : tree.createNodeChild(path[d], pos);
		}
		valid = depth;
		tree.updateNodeLogOdds(path[depth], update);
		prev = c;
	}
}

/** Sorts 48-bit codes: three counting passes of 16 bits, least significant
 * first, linear in the number of codes (a keyframe has ~10^6). */
void radixSort48(std::vector<uint64_t>& v, std::vector<uint64_t>& buffer)
{
	buffer.resize(v.size());
	for (int shift = 0; shift < 48; shift += 16)
	{
		std::vector<uint32_t> count(65537, 0);
		for (uint64_t x : v) count[((x >> shift) & 0xffff) + 1]++;
		for (size_t i = 1; i < count.size(); i++) count[i] += count[i - 1];
		for (uint64_t x : v) buffer[count[(x >> shift) & 0xffff]++] = x;
		v.swap(buffer);
	}
}
}  // namespace

struct DiscreteRayCaster::Impl
{
	explicit Impl(double resolution_m) : keys(resolution_m) {}
	octomap::OcTree keys;  ///< for its key arithmetic only (stays empty)
	octomap::KeyRay ray;
	core::FlatHashMap<uint8_t> ends;  ///< end voxels seen (Morton codes)
	octomap::Pointcloud discrete;
	/** Codes as the rays cross them, repeats included, then sorted and made
	 * unique: appending is sequential where a hash set probed a big table
	 * at random for every ray step (a cache miss each). */
	std::vector<uint64_t> free_codes, occupied_codes, sort_buffer;
	/** The codes appended last, by a hash of the code: the voxels near the
	 * sensor, which most rays cross, are appended once, not per ray. */
	static constexpr size_t kRecent = 4096;
	std::vector<uint64_t> recent = std::vector<uint64_t>(kRecent, ~0ull);
};

DiscreteRayCaster::DiscreteRayCaster(double resolution_m)
    : impl_(std::make_unique<Impl>(resolution_m))
{
}
DiscreteRayCaster::~DiscreteRayCaster() = default;

void DiscreteRayCaster::cast(const octomap::Pointcloud& cloud,
                             const octomap::point3d& origin, double max_range_m,
                             std::vector<octomap::OcTreeKey>& free,
                             std::vector<octomap::OcTreeKey>& occupied)
{
	std::vector<uint64_t> free_codes, occupied_codes;
	castCodes(cloud, origin, max_range_m, free_codes, occupied_codes);
	free.clear();
	occupied.clear();
	free.reserve(free_codes.size());
	occupied.reserve(occupied_codes.size());
	for (uint64_t c : free_codes) free.push_back(fromMorton(c));
	for (uint64_t c : occupied_codes) occupied.push_back(fromMorton(c));
}

void DiscreteRayCaster::castCodes(const octomap::Pointcloud& cloud,
                                  const octomap::point3d& origin,
                                  double max_range_m,
                                  std::vector<uint64_t>& free,
                                  std::vector<uint64_t>& occupied)
{
	Impl& m = *impl_;
	m.ends.clearKeepingCapacity();
	m.free_codes.clear();
	m.occupied_codes.clear();
	std::fill(m.recent.begin(), m.recent.end(), ~0ull);
	m.discrete.clear();
	// computeDiscreteUpdate: one end point per voxel, its centre, in the
	// order the voxels first appear.
	for (size_t i = 0; i < cloud.size(); i++)
	{
		const octomap::OcTreeKey k = m.keys.coordToKey(cloud[i]);
		bool added = false;
		m.ends.tryEmplace(morton(k), &added);
		if (added) m.discrete.push_back(m.keys.keyToCoord(k));
	}
	// computeUpdate without a bounding box, the same float arithmetic.
	auto markFree = [&]()
	{
		for (const auto& k : m.ray)
		{
			const uint64_t code = morton(k);
			uint64_t& seen = m.recent[(code * 0x9e3779b97f4a7c15ull) >> 52];
			if (seen == code) continue;
			seen = code;
			m.free_codes.push_back(code);
		}
	};
	for (size_t i = 0; i < m.discrete.size(); i++)
	{
		const octomap::point3d& p = m.discrete[i];
		if (max_range_m < 0.0 || (p - origin).norm() <= max_range_m)
		{
			if (m.keys.computeRayKeys(origin, p, m.ray)) markFree();
			octomap::OcTreeKey key;
			if (m.keys.coordToKeyChecked(p, key))
				m.occupied_codes.push_back(morton(key));
		}
		else
		{
			const octomap::point3d direction = (p - origin).normalized();
			const octomap::point3d new_end =
			    origin + direction * static_cast<float>(max_range_m);
			if (m.keys.computeRayKeys(origin, new_end, m.ray)) markFree();
		}
	}
	// Sets in tree order; a voxel both free and occupied is occupied.
	for (auto* codes : {&m.free_codes, &m.occupied_codes})
	{
		radixSort48(*codes, m.sort_buffer);
		codes->erase(std::unique(codes->begin(), codes->end()), codes->end());
	}
	free.clear();
	free.reserve(m.free_codes.size());
	auto occ = m.occupied_codes.begin();
	for (uint64_t c : m.free_codes)
	{
		while (occ != m.occupied_codes.end() && *occ < c) ++occ;
		if (occ == m.occupied_codes.end() || *occ != c) free.push_back(c);
	}
	occupied = m.occupied_codes;
}

OctomapSummary writeOctomap(const Keyframes& keyframes,
                            const KeyframeCloudLoader& cloud_of,
                            double resolution_m, double max_range_m,
                            const std::string& bt_path,
                            const std::string& ot_path,
                            double keyframe_spacing_m)
{
	const auto t0 = std::chrono::steady_clock::now();
	OctomapSummary s;
	const std::vector<size_t> cast_kf =
	    spacedKeyframes(keyframes, keyframe_spacing_m);
	s.keyframes_skipped = keyframes.size() - cast_kf.size();
	octomap::OcTree tree(resolution_m);
	// Ray casting (the keys a keyframe's rays cross) runs for the next two
	// keyframes on two threads while keyframe i's keys update the tree, in
	// tree order (Morton order: the updates, not the casting, were most of
	// the handheld run's 34.7 s; 18.9 s with both). Each casting has its own
	// DiscreteRayCaster (the keys computeDiscreteUpdate finds, in flat
	// tables), and the updates are insertPointCloud's (discretize,
	// lazy_eval) in keyframe order: the same file.
	struct Rays
	{
		std::vector<uint64_t> free, occupied;  ///< Morton codes, tree order
		size_t points = 0;
	};
	constexpr size_t kCasters = 2;
	std::vector<std::unique_ptr<DiscreteRayCaster>> casters;
	for (size_t c = 0; c < kCasters; c++)
		casters.push_back(std::make_unique<DiscreteRayCaster>(resolution_m));
	auto cast = [&](size_t i, DiscreteRayCaster& caster)
	{
		const auto& kf = keyframes[i];
		const std::vector<Eigen::Vector3f> pts = cloud_of(i);
		octomap::Pointcloud cloud;
		cloud.reserve(pts.size());
		const Eigen::Isometry3f T = kf.sensor_pose.cast<float>();
		for (const auto& p : pts)
		{
			const Eigen::Vector3f q = T * p;
			cloud.push_back(q.x(), q.y(), q.z());
		}
		const auto& o = kf.sensor_pose.translation();
		Rays r;
		r.points = pts.size();
		// discretize: one ray per end voxel (several points in one voxel
		// would cast the same ray).
		caster.castCodes(cloud, octomap::point3d(o.x(), o.y(), o.z()),
		                 max_range_m, r.free, r.occupied);
		return r;
	};
	// Keyframe j is cast on casters[j % kCasters]; its future is
	// pending[j % kCasters].
	std::vector<std::future<Rays>> pending(kCasters);
	auto launch = [&](size_t j)
	{
		if (j < cast_kf.size())
			pending[j % kCasters] =
			    std::async(std::launch::async, cast, cast_kf[j],
			               std::ref(*casters[j % kCasters]));
	};
	for (size_t j = 0; j < kCasters; j++) launch(j);
	for (size_t j = 0; j < cast_kf.size(); j++)
	{
		const Rays r = pending[j % kCasters].get();  // rethrows a loader error
		launch(j + kCasters);
		// lazy_eval: inner nodes are updated once at the end.
		updateInTreeOrder(tree, r.free, false);
		updateInTreeOrder(tree, r.occupied, true);
		s.keyframes++;
		s.rays += r.points;
	}
	tree.updateInnerOccupancy();
	for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
		(tree.isNodeOccupied(*it) ? s.occupied_leaves : s.free_leaves)++;
	if (!tree.writeBinary(core::tempPathFor(bt_path)))
		throw std::runtime_error("cannot write OctoMap '" + bt_path + "'");
	core::commitTempFile(bt_path);
	if (!ot_path.empty()) writeColourTree(tree, ot_path);
	s.seconds =
	    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
	        .count();
	return s;
}

}  // namespace forest_slam::outputs
