#include <forest_slam/core/atomic_file.h>
#include <forest_slam/core/memory.h>
#include <forest_slam/trees/column_input.h>
#include <forest_slam/trees/stem_detector.h>
#include <forest_slam/trees/terrain_model.h>
#include <forest_slam/trees/tree_layer.h>
#include <pthread.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>

namespace forest_slam::trees
{
namespace
{
/** Two columns are detected (finish) or moved (correct) at once unless
 * they hold more stem voxels than this together (memory at the end of a
 * long run). */
constexpr size_t kTwoAtOnceVoxels = 4000000;

/** Points whose findTrees buffers a thread keeps between columns (40 MB). */
constexpr size_t kKeptScratchPoints = size_t(1) << 20;

/** findTrees' per-thread buffers. */
struct ColumnScratch
{
	ColumnInput in;
	std::vector<Eigen::Vector3f> above;
	void clear() { in.clear(), above.clear(); }
	/** Frees the buffers that grew past `points` (a big column's): kept,
	 * each thread held the capacity of the biggest column it had seen, so
	 * the two threads of the end-of-run detection held two big columns'
	 * buffers whatever they read (kTwoAtOnceVoxels bounded the work only);
	 * the 58-minute run peaked there, 330 MB above its correction. */
	void trim(size_t points)
	{
		in.trim(points);
		if (above.capacity() > points)
			std::vector<Eigen::Vector3f>().swap(above);
	}
};
ColumnScratch& columnScratch()
{
	thread_local ColumnScratch s;
	return s;
}
}  // namespace

namespace
{
double msSince(std::chrono::steady_clock::time_point t0)
{
	return std::chrono::duration<double, std::milli>(
	           std::chrono::steady_clock::now() - t0)
	    .count();
}

/** Adds the calling thread's CPU time [ms] from construction to
 * destruction to `to` (TreeLayerStats::cpu_ms). */
class CpuTally
{
   public:
	explicit CpuTally(double& to) : to_(to), c0_(core::threadCpuSeconds()) {}
	~CpuTally() { to_ += 1000 * (core::threadCpuSeconds() - c0_); }
	CpuTally(const CpuTally&) = delete;
	CpuTally& operator=(const CpuTally&) = delete;

   private:
	double& to_;
	const double c0_;
};

/** Starts `work` on a second thread; its CPU time [ms] is added to
 * `cpu_ms` when joined. */
class SecondThread
{
   public:
	template <class F>
	SecondThread(F& work, double& cpu_ms)
	    : cpu_ms_(cpu_ms),
	      t_(
	          [this, &work]
	          {
		          pthread_setname_np(pthread_self(), "fs-trees2");
		          const double c0 = core::threadCpuSeconds();
		          work();
		          thread_ms_ = 1000 * (core::threadCpuSeconds() - c0);
	          })
	{
	}
	~SecondThread()
	{
		t_.join();
		cpu_ms_ += thread_ms_;
	}

   private:
	double& cpu_ms_;
	double thread_ms_ = 0;
	std::thread t_;
};

/** Horizontal distance from (x, y) to the square [x0, x0+s] × [y0, y0+s]. */
double distanceToSquare(double x, double y, double x0, double y0, double s)
{
	const double dx = std::max({x0 - x, 0.0, x - (x0 + s)});
	const double dy = std::max({y0 - y, 0.0, y - (y0 + s)});
	return std::hypot(dx, dy);
}
}  // namespace

// --------------------------------------------------------- SortedVoxels
namespace
{
/** Points buffered per column (9.6 MB: the memory 200 000 points held in
 * 48-byte voxels; each merge rewrites the column, so fewer merges). */
constexpr size_t kMaxPending = 300000;
/** Read buffers kept by a detecting thread between reads (32 MB). */
constexpr size_t kKeptReadVoxels = size_t(1) << 20;
/** Voxels read from each run at a time when reload() merges runs (2 MB). */
constexpr size_t kReadRunChunk = size_t(1) << 16;
constexpr int64_t kKeyOffset = int64_t(1) << 20;  ///< 21 bits per axis
/** `v`'s points into `m`: the mean offset and direction weighted by the
 * counts, each rounded once (the time is left to the caller). */
template <class V>
void addMeans(V& m, const V& v)
{
	const float w = float(v.count) / float(m.count + v.count);
	for (int i = 0; i < 3; i++)
	{
		m.offset[i] = int16_t(core::roundToLong(
		    float(m.offset[i]) + w * float(v.offset[i] - m.offset[i])));
		m.dir[i] = int16_t(core::roundToLong(float(m.dir[i]) +
		                                     w * float(v.dir[i] - m.dir[i])));
	}
	m.count += v.count;
}
}  // namespace

uint64_t TreeLayer::SortedVoxels::keyOf(const Eigen::Vector3f& p) const
{
	auto axis = [&](float v)
	{
		const int64_t i = core::floorToInt(double(v) / voxel_m_) + kKeyOffset;
		return uint64_t(std::clamp<int64_t>(i, 0, (int64_t(1) << 21) - 1));
	};
	return (axis(p.x()) << 42) | (axis(p.y()) << 21) | axis(p.z());
}

Eigen::Vector3f TreeLayer::SortedVoxels::centreOf(uint64_t key) const
{
	const uint64_t m = (uint64_t(1) << 21) - 1;
	auto axis = [&](uint64_t i)
	{ return float((double(int64_t(i) - kKeyOffset) + 0.5) * voxel_m_); };
	return {axis((key >> 42) & m), axis((key >> 21) & m), axis(key & m)};
}

void TreeLayer::SortedVoxels::compact(size_t max_pending)
{
	static_assert(sizeof(Voxel) == 32, "stem-band voxel grew");
	if (!pending_.empty() && pending_.size() > max_pending) mergeIn(pending_);
	// The buffer's capacity stays between the merges of a column taking
	// points (grown afresh after every merge, its reallocations were a
	// tenth of the store's CPU); a full compaction (before detections,
	// moves and spills) frees it: otherwise each resident column would
	// hold up to kMaxPending voxels (~10 MB) through the end-of-run
	// detection, where a long run's peak RSS is.
	if (max_pending == 0)
		std::vector<Voxel>().swap(pending_);
	else if (pending_.size() > max_pending)
		pending_.clear();
}

void TreeLayer::SortedVoxels::transform(const Eigen::Isometry3f& T)
{
	compact();
	// Centroids move exactly; voxels meeting in one cell are merged. In
	// place: a long run's column holds millions of voxels, and a moved
	// copy plus a merged one tripled it at the final correction.
	for (auto& v : voxels_)
	{
		const Eigen::Vector3f c = T * centroid(v);
		v.key = keyOf(c);
		setOffset(v, c - centreOf(v.key));
		setDir(v, T.linear() * dirOf(v));
	}
	sortAndCombine();
}

float TreeLayer::SortedVoxels::transformByTime(
    const std::function<Eigen::Isometry3f(float)>& at,
    const Eigen::Isometry3f& T, bool dominant_time, uint32_t last_pass)
{
	compact();
	// The passes merged; the later ones keep their number (the pass field
	// saturates, and so does the comparison).
	const auto merged = [last = std::min<uint32_t>(last_pass, 0xffff)](
	                        const Voxel& v) { return v.pass <= last; };
	// The largest squared distance (one square root at the end, not one
	// per voxel: the same value, as the root is monotonic).
	float worst2 = 0;
	for (auto& v : voxels_)  // in place, as transform()
	{
		if (!merged(v)) continue;
		const Eigen::Isometry3f C = at(v.time);
		const Eigen::Vector3f c0 = centroid(v), c = C * c0;
		worst2 = std::max(worst2, (c - T * c0).squaredNorm());
		v.key = keyOf(c);
		setOffset(v, c - centreOf(v.key));
		setDir(v, C.linear() * dirOf(v));
		// Corrected, the passes agree: merged again (pass 0).
		if (!dominant_time) v.pass = 0;
	}
	const float worst = std::sqrt(worst2);
	sortAndCombine();
	if (!dominant_time) return worst;
	// Within a pass the times were averaged (sortAndCombine); across the
	// merged passes the time of the largest count stays: each cell's
	// voxels (sorted by key already) ordered by pass after the merge, then
	// segment, then count, largest first. A stable insertion sort per cell
	// (a few voxels: its passes and segments), the same order as a stable
	// sort of the whole set, which took a buffer as large as the set (a
	// long run's column: hundreds of MB at once).
	const auto passAfter = [&](const Voxel& v) -> uint16_t
	{ return merged(v) ? 0 : v.pass; };
	const auto before = [&](const Voxel& a, const Voxel& b)
	{
		const uint16_t pa = passAfter(a), pb = passAfter(b);
		return pa != pb                 ? pa < pb
		       : a.segment != b.segment ? a.segment < b.segment
		                                : a.count > b.count;
	};
	for (size_t g = 0; g < voxels_.size();)
	{
		size_t e = g + 1;
		while (e < voxels_.size() && voxels_[e].key == voxels_[g].key) e++;
		for (size_t i = g + 1; i < e; i++)
		{
			const Voxel v = voxels_[i];
			size_t j = i;
			for (; j > g && before(v, voxels_[j - 1]); j--)
				voxels_[j] = voxels_[j - 1];
			voxels_[j] = v;
		}
		g = e;
	}
	size_t w = 0;
	for (size_t i = 0; i < voxels_.size(); i++)
	{
		const Voxel& v = voxels_[i];
		if (i > 0 && voxels_[w].key == v.key &&
		    voxels_[w].segment == v.segment && voxels_[w].pass == passAfter(v))
			addMeans(voxels_[w], v);
		else
		{
			if (i > 0) w++;
			voxels_[w] = v;
			voxels_[w].pass = passAfter(v);
		}
	}
	voxels_.resize(voxels_.empty() ? 0 : w + 1);
	return worst;
}

namespace
{
/** Sorted by cell, pass, segment. */
template <class V>
bool voxelLess(const V& a, const V& b)
{
	return a.key != b.key     ? a.key < b.key
	       : a.pass != b.pass ? a.pass < b.pass
	                          : a.segment < b.segment;
}
/** Whether `a` and `b` are one voxel: same cell, pass and segment. */
template <class V>
bool sameVoxel(const V& a, const V& b)
{
	return a.key == b.key && a.pass == b.pass && a.segment == b.segment;
}
/** The lowest and highest pass of `v`'s voxels. */
template <class V>
std::pair<uint16_t, uint16_t> passRange(const std::vector<V>& v)
{
	uint16_t lo = 0xffff, hi = 0;
	for (const auto& x : v)
		lo = std::min(lo, x.pass), hi = std::max(hi, x.pass);
	return {lo, hi};
}
}  // namespace

TreeLayer::SortedVoxels::SpillWrite TreeLayer::SortedVoxels::spill(
    core::SpillFile& f)
{
	compact();
	std::vector<Voxel>().swap(pending_);  // its capacity too
	SpillWrite wrote = SpillWrite::nothing;
	if (spilled_)
	{
		if (voxels_.empty()) return wrote;
		// New voxels all of passes after those on disk (the sensor came
		// back after a loop correction: the usual revisit) share no voxel
		// with the copy: appended as they are, the copy is not read.
		const auto [lo, hi] = passRange(voxels_);
		const int max_runs = std::clamp(spill_max_runs, 1, kMaxRuns);
		if (n_runs_ == 0 || (n_runs_ < max_runs && lo > disk_max_pass_))
		{
			runs_[n_runs_++] = {f.appendVector(voxels_), voxels_.size()};
			disk_count_ += voxels_.size();
			disk_max_pass_ = std::max(disk_max_pass_, hi);
			std::vector<Voxel>().swap(voxels_);
			return SpillWrite::appended;
		}
		spillMerged(f, hi);
		return SpillWrite::merged;
	}
	if (changed_)
	{
		// The copy on disk is out of date: its space goes back.
		discardRuns(f);
		if (!voxels_.empty())
		{
			runs_[0] = {f.appendVector(voxels_), voxels_.size()};
			n_runs_ = 1;
			disk_count_ = voxels_.size();
			disk_max_pass_ = passRange(voxels_).second;
		}
		wrote = SpillWrite::whole;
	}
	std::vector<Voxel>().swap(voxels_);
	spilled_ = true;
	changed_ = false;
	return wrote;
}

void TreeLayer::SortedVoxels::discardRuns(core::SpillFile& f)
{
	for (int r = 0; r < n_runs_; r++)
		if (runs_[r].count > 0)
			f.discard(runs_[r].offset, runs_[r].count * sizeof(Voxel));
	n_runs_ = 0;
	disk_count_ = 0;
	disk_max_pass_ = 0;
}

void TreeLayer::SortedVoxels::mergeSorted(std::vector<Voxel>& a,
                                          const std::vector<Voxel>& b)
{
	// In place, from the back (a merged copy, allocated afresh on every
	// merge, came back as page faults).
	const size_t n_a = a.size();
	a.resize(n_a + b.size());
	Voxel* A = a.data();
	const Voxel* B = b.data();
	size_t i = n_a, j = b.size(), w = a.size();
	while (j > 0)
		if (i > 0 && voxelLess(B[j - 1], A[i - 1]))
			A[--w] = A[--i];
		else
			A[--w] = B[--j];
}

struct TreeLayer::SortedVoxels::ReadBuffers
{
	SortedVoxels copy;
	std::vector<Voxel> added, chunk, run;
};

void TreeLayer::SortedVoxels::readRuns(const core::SpillFile& f,
                                       std::vector<Voxel>& out) const
{
	out.clear();
	if (n_runs_ == 0) return;
	// Room for all first: memory met for the first time costs a page
	// fault per 4 KB, more than reading it from the file.
	out.reserve(disk_count_);
	if (n_runs_ == 1)
	{
		f.readVector(runs_[0].offset, runs_[0].count, out);
		return;
	}
	// The runs merged as they are read, each voxel moved once (merging
	// each later run into the ones before moved the first run's voxels
	// once per run).
	forEachMerged(f, kReadRunChunk, false,
	              [&](const Voxel& v) { out.push_back(v); });
}

void TreeLayer::SortedVoxels::reload(const core::SpillFile& f)
{
	if (!spilled_) return;
	compact();
	std::vector<Voxel> added;
	added.swap(voxels_);
	readRuns(f, voxels_);  // the runs stay on disk: a copy until changed
	spilled_ = false;
	changed_ = false;
	if (!added.empty()) mergeIn(added);  // sets changed_
}

TreeLayer::SortedVoxels::ReadBuffers& TreeLayer::SortedVoxels::readBuffers()
{
	thread_local ReadBuffers b;
	return b;
}

void TreeLayer::SortedVoxels::freeReadBuffers()
{
	auto& b = readBuffers();
	b.copy = SortedVoxels();
	std::vector<Voxel>().swap(b.added);
	std::vector<Voxel>().swap(b.chunk);
	std::vector<Voxel>().swap(b.run);
}

void TreeLayer::SortedVoxels::trimReadBuffers(size_t voxels)
{
	auto& b = readBuffers();
	for (auto* v : {&b.copy.voxels_, &b.added, &b.run})
		if (v->capacity() > voxels) std::vector<Voxel>().swap(*v);
}

void TreeLayer::SortedVoxels::loadInto(const core::SpillFile* f,
                                       const Eigen::Vector2f& lo,
                                       const Eigen::Vector2f& hi,
                                       SortedVoxels& copy) const
{
	// Cell index ranges of the box (keys hold the cell indices per axis).
	const uint64_t m = (uint64_t(1) << 21) - 1;
	auto cells = [&](float a, float b)
	{
		const float big = 1e7f;  // beyond any key: the whole axis
		const uint64_t i0 = keyOf({std::clamp(a, -big, big), 0, 0}) >> 42;
		const uint64_t i1 = keyOf({std::clamp(b, -big, big), 0, 0}) >> 42;
		return std::make_pair(i0, i1);
	};
	const auto [x0, x1] = cells(lo.x(), hi.x());
	const auto [y0, y1] = cells(lo.y(), hi.y());
	auto inBox = [&](const Voxel& v)
	{
		const uint64_t ix = v.key >> 42, iy = (v.key >> 21) & m;
		return ix >= x0 && ix <= x1 && iy >= y0 && iy <= y1;
	};
	// The buffers stay with the thread: a detection reads nine columns, and
	// fresh vectors of tens of MB came back as page faults (a tenth of the
	// end-of-run detection).
	copy.setVoxelSize(voxel_m_);
	copy.voxels_.clear();
	copy.pending_.clear();
	copy.spilled_ = false;
	copy.n_runs_ = 0;
	copy.disk_count_ = 0;
	auto& added = readBuffers().added;
	auto& chunk = readBuffers().chunk;
	auto& in_run = readBuffers().run;
	// Sorted on disk: in each run, the stretch of keys with x cells in
	// [x0, x1], found by bisection (a few dozen reads of one voxel), stays
	// sorted. The first run straight into the copy, the others merged in
	// (no voxel in two runs).
	struct Stretch
	{
		size_t begin = 0, end = 0;
	};
	std::array<Stretch, kMaxRuns> stretch;
	size_t left = 0;  // voxels of the stretches not read yet
	for (int r = 0; spilled_ && r < n_runs_; r++)
	{
		const Run& run = runs_[r];
		auto firstAtLeast = [&](uint64_t key)
		{
			size_t a = 0, b = run.count;
			Voxel v;
			while (a < b)
			{
				const size_t mid = a + (b - a) / 2;
				f->read(run.offset + mid * sizeof(Voxel), &v, sizeof(Voxel));
				if (v.key < key)
					a = mid + 1;
				else
					b = mid;
			}
			return a;
		};
		stretch[r].begin = firstAtLeast(x0 << 42);
		stretch[r].end = x1 >= m ? run.count : firstAtLeast((x1 + 1) << 42);
		left += stretch[r].end - stretch[r].begin;
	}
	constexpr size_t kChunk = size_t(1) << 18;
	bool reserved = left <= kChunk;
	for (int r = 0; spilled_ && r < n_runs_; r++)
	{
		std::vector<Voxel>& to = r == 0 ? copy.voxels_ : in_run;
		to.clear();
		for (size_t at = stretch[r].begin; at < stretch[r].end; at += kChunk)
		{
			const size_t n = std::min(kChunk, stretch[r].end - at);
			f->readVector(runs_[r].offset + at * sizeof(Voxel), n, chunk);
			const size_t kept_before = to.size();
			for (const auto& v : chunk)
				if (inBox(v)) to.push_back(v);
			left -= n;
			// Room for the rest at the first chunk's share in the box: a
			// whole column's copy grown by doubling held 1.5-2 copies at
			// once (the 60-minute run's peak RSS, during the detections);
			// the later runs are merged into it.
			if (!reserved)
			{
				const size_t kept = to.size() - kept_before;
				copy.voxels_.reserve(copy.voxels_.size() +
				                     (r > 0 ? to.size() : 0) + left * kept / n +
				                     n / 16);
				reserved = true;
			}
		}
		if (r > 0) mergeSorted(copy.voxels_, in_run);
	}
	added.clear();  // in memory: all, or those added since spilled
	for (const auto& v : voxels_)
		if (inBox(v)) added.push_back(v);
	for (const auto& v : pending_)
		if (inBox(v)) added.push_back(v);
	if (!added.empty()) copy.mergeIn(added);
}

namespace
{
/** Sorts [a, e), voxels of one x cell, by voxelLess: a radix sort on the
 * y and z cells (least significant digit first, through `tmp`), then the
 * few voxels of one cell put in (pass, segment) order. Where the y and z
 * cells need more than 24 bits together (spans of ~80 m each), or the
 * bucket is tiny, std::sort. The per-bucket std::sort was 1.6 % of a robot
 * run's CPU (the radix sort: 10 instead of 39 ns a voxel on a column's buffered
 * points, 11 instead of 21 on a corrected column). Equal voxels (the
 * buffered points of one cell) come out in another order than
 * std::sort's, so their sums round differently (the last bit). */
template <class V>
void sortBucket(V* a, V* e, std::vector<V>& tmp)
{
	const size_t n = size_t(e - a);
	const auto less = [](const V& x, const V& y) { return voxelLess(x, y); };
	constexpr size_t kMinRadix = 64;
	if (n < kMinRadix)
	{
		std::sort(a, e, less);
		return;
	}
	const uint64_t m = (uint64_t(1) << 21) - 1;
	uint64_t ylo = m, yhi = 0, zlo = m, zhi = 0;
	for (const V* p = a; p != e; p++)
	{
		const uint64_t y = (p->key >> 21) & m, z = p->key & m;
		ylo = std::min(ylo, y), yhi = std::max(yhi, y);
		zlo = std::min(zlo, z), zhi = std::max(zhi, z);
	}
	const auto bitsFor = [](uint64_t span)
	{ return 64 - __builtin_clzll(span | 1); };
	const int zb = bitsFor(zhi - zlo), bits = bitsFor(yhi - ylo) + zb;
	constexpr int kMaxBits = 24;
	if (bits > kMaxBits)
	{
		std::sort(a, e, less);
		return;
	}
	const auto code = [&](const V& x)
	{
		return uint32_t(((x.key >> 21) & m) - ylo) << zb |
		       uint32_t((x.key & m) - zlo);
	};
	const int passes = bits <= kMaxBits / 2 ? 1 : 2;
	const int digit = (bits + passes - 1) / passes;
	const uint32_t mask = (uint32_t(1) << digit) - 1;
	uint32_t count[uint32_t(1) << (kMaxBits / 2)];
	tmp.resize(n);
	V *src = a, *dst = tmp.data();
	for (int p = 0; p < passes; p++)
	{
		const int shift = p * digit;
		std::fill(count, count + mask + 1, 0u);
		for (size_t i = 0; i < n; i++) count[(code(src[i]) >> shift) & mask]++;
		uint32_t sum = 0;
		for (uint32_t d = 0; d <= mask; d++)
			sum += std::exchange(count[d], sum);
		for (size_t i = 0; i < n; i++)
			dst[count[(code(src[i]) >> shift) & mask]++] = src[i];
		std::swap(src, dst);
	}
	if (src != a) std::copy(src, src + n, a);
	for (size_t i = 1; i < n; i++)
	{
		if (!(a[i].key == a[i - 1].key && less(a[i], a[i - 1]))) continue;
		const V x = a[i];
		size_t j = i;
		for (; j > 0 && a[j - 1].key == x.key && less(x, a[j - 1]); j--)
			a[j] = a[j - 1];
		a[j] = x;
	}
}
/** Sorts by voxelLess. Bucketed first by the key's x cell (its top bits: a
 * column spans ~1000 cells), in place (American flag sort), then each
 * bucket sorted on its own, in cache: one std::sort of a column's millions
 * of voxels was 2 % of a robot run's CPU. Small or widely spread sets (a
 * single bucket array would be large) are sorted whole. */
template <class V>
void sortVoxels(std::vector<V>& v)
{
	constexpr size_t kMinBucketed = 4096;
	constexpr uint64_t kMaxBuckets = uint64_t(1) << 16;
	const auto less = [](const V& a, const V& b) { return voxelLess(a, b); };
	if (v.size() < kMinBucketed)
	{
		std::sort(v.begin(), v.end(), less);
		return;
	}
	uint64_t lo = ~uint64_t(0), hi = 0;
	for (const V& x : v)
		lo = std::min(lo, x.key >> 42), hi = std::max(hi, x.key >> 42);
	const uint64_t nb = hi - lo + 1;
	if (nb > kMaxBuckets || nb == 1)
	{
		std::sort(v.begin(), v.end(), less);
		return;
	}
	std::vector<size_t> start(nb + 1, 0);
	for (const V& x : v) start[(x.key >> 42) - lo + 1]++;
	for (size_t b = 0; b < nb; b++) start[b + 1] += start[b];
	std::vector<size_t> next(start.begin(), start.end() - 1);
	for (size_t b = 0; b < nb; b++)
		while (next[b] < start[b + 1])
		{
			// Carry the voxel at bucket b's next free slot to its bucket's
			// next free slot, the one there onwards, until one of b's.
			V x = v[next[b]];
			for (size_t t = (x.key >> 42) - lo; t != b; t = (x.key >> 42) - lo)
				std::swap(x, v[next[t]++]);
			v[next[b]++] = x;
		}
	std::vector<V> tmp;  // the largest bucket's size
	for (size_t b = 0; b < nb; b++)
		sortBucket(v.data() + start[b], v.data() + start[b + 1], tmp);
}
/** `v` into `m` (same key, pass and segment): the time averaged too. */
template <class V>
void combine(V& m, const V& v)
{
	m.time = float((double(m.time) * m.count + double(v.time) * v.count) /
	               double(m.count + v.count));
	addMeans(m, v);
}
}  // namespace

void TreeLayer::SortedVoxels::sortAndCombine()
{
	changed_ = true;
	sortVoxels(voxels_);
	size_t w = 0;
	for (size_t i = 1; i < voxels_.size(); i++)
	{
		const Voxel& v = voxels_[i];
		Voxel& m = voxels_[w];
		if (sameVoxel(m, v))
			combine(m, v);
		else
			voxels_[++w] = v;
	}
	voxels_.resize(voxels_.empty() ? 0 : w + 1);
}

void TreeLayer::SortedVoxels::mergeIn(std::vector<Voxel>& add)
{
	if (voxels_.empty())
	{
		voxels_.swap(add);
		sortAndCombine();
		return;
	}
	changed_ = true;
	sortVoxels(add);
	// Equal voxels end up next to each other, the older first as in a
	// forward merge, and are then summed in that order.
	mergeSorted(voxels_, add);
	size_t u = 0;
	for (size_t k = 1; k < voxels_.size(); k++)
		if (sameVoxel(voxels_[u], voxels_[k]))
			combine(voxels_[u], voxels_[k]);
		else
			voxels_[++u] = voxels_[k];
	voxels_.resize(u + 1);
}

template <class F>
void TreeLayer::SortedVoxels::forEachMerged(const core::SpillFile& f,
                                            size_t chunk, bool with_memory,
                                            F&& take) const
{
	struct Cursor
	{
		const Run* run = nullptr;  // null: the voxels in memory
		std::vector<Voxel> in;
		size_t i = 0, read = 0;
	};
	// The runs in their order, then the voxels in memory: an equal voxel
	// is taken from the earlier source first (the older, as in mergeIn).
	std::vector<Cursor> src(size_t(n_runs_) + (with_memory ? 1 : 0));
	for (int r = 0; r < n_runs_; r++) src[size_t(r)].run = &runs_[r];
	const auto head = [&](Cursor& c) -> const Voxel*
	{
		if (!c.run) return c.i < voxels_.size() ? &voxels_[c.i] : nullptr;
		if (c.i == c.in.size() && c.read < c.run->count)
		{
			const size_t n = std::min(chunk, c.run->count - c.read);
			c.in.resize(n);
			f.read(c.run->offset + c.read * sizeof(Voxel), c.in.data(),
			       n * sizeof(Voxel));
			c.read += n;
			c.i = 0;
		}
		return c.i < c.in.size() ? &c.in[c.i] : nullptr;
	};
	for (;;)
	{
		Cursor* best = nullptr;
		const Voxel* best_v = nullptr;
		for (auto& c : src)
			if (const Voxel* v = head(c);
			    v && (!best_v || voxelLess(*v, *best_v)))
				best = &c, best_v = v;
		if (!best) break;
		take(*best_v);
		best->i++;
	}
}

void TreeLayer::SortedVoxels::spillMerged(core::SpillFile& f,
                                          uint16_t new_max_pass)
{
	// voxels_ (sorted and combined: compact() ran) holds what was added
	// since the set went to disk. Reading the set back whole and merging in
	// memory held it twice over: on the 58-minute run, spikes of up to
	// 700 MB for a second whenever the sensor left a revisited column. The same
	// forward merge as mergeIn() (the result is the same, bit for bit)
	// streams instead: the runs on disk read and the merged set written in
	// chunks, into a region set aside for the largest possible result.
	const size_t kChunk = std::max<size_t>(1, spill_merge_chunk_voxels);
	const size_t upper = disk_count_ + voxels_.size();
	const uint64_t out = f.reserve(upper * sizeof(Voxel));
	std::vector<Voxel> buf;
	buf.reserve(kChunk + 1);
	size_t written = 0;
	const auto flush = [&](bool all)
	{
		// Unless at the end, the last voxel may still combine with the next.
		const size_t n = all ? buf.size() : buf.size() - 1;
		if (n == 0) return;
		f.overwrite(out + written * sizeof(Voxel), buf.data(),
		            n * sizeof(Voxel));
		written += n;
		buf.erase(buf.begin(), buf.begin() + n);
	};
	const auto push = [&](const Voxel& v)
	{
		if (!buf.empty() && sameVoxel(buf.back(), v))
			combine(buf.back(), v);
		else if (buf.push_back(v); buf.size() > kChunk)
			flush(false);
	};
	forEachMerged(f, kChunk, true, push);
	flush(true);
	const uint16_t max_pass = std::max(disk_max_pass_, new_max_pass);
	discardRuns(f);
	if (written < upper)
		f.discard(out + written * sizeof(Voxel),
		          (upper - written) * sizeof(Voxel));
	disk_max_pass_ = max_pass;
	runs_[0] = {out, written};
	n_runs_ = written > 0 ? 1 : 0;
	disk_count_ = written;
	std::vector<Voxel>().swap(voxels_);
	spilled_ = true;
	changed_ = false;
}

// ------------------------------------------------------------ TreeLayer
TreeLayer::TreeLayer(const TreeOptions& o, double column_size_m,
                     bool detect_during_run)
    : o_(o), column_m_(column_size_m), detect_during_run_(detect_during_run)
{
	if (o.layer_spill_to_disk) spill_ = std::make_unique<core::SpillFile>();
	if (!o.layer_dump_dir.empty()) core::ensureDirectory(o.layer_dump_dir);
}

TreeLayer::SortedVoxels& TreeLayer::resident(Column& c)
{
	if (c.stem.spilled()) c.stem.reload(*spill_);
	return c.stem;
}

const TreeLayer::SortedVoxels& TreeLayer::readable(
    const Column& c, SortedVoxels& copy, const Eigen::Vector2f& lo,
    const Eigen::Vector2f& hi) const
{
	if (!c.stem.spilled() && c.stem.compacted()) return c.stem;
	// A neighbour's margin strip only: a long run's column holds millions
	// of voxels, and every detection read its eight neighbours whole.
	c.stem.loadInto(spill_.get(), lo, hi, copy);
	return copy;
}

void TreeLayer::spillFar(const Eigen::Vector3d& sensor)
{
	if (!spill_) return;
	const CpuTally cpu(stats_.spill_cpu_ms);  // update() counts it in cpu_ms
	// Beyond the reach of new points (which would not read it back). A
	// column due for detection during the run stays until then (it would
	// be written twice); one changed but left for the end of the run
	// (layer_redetect_growth) goes. Detections read a spilled column
	// without keeping it.
	const double far = o_.layer_max_range_m;
	for (auto& [k, c] : cols_)
		if (!dueInRun(c) && c.stem.sizeInMemory() > 0 &&
		    distanceToSquare(sensor.x(), sensor.y(), k.x * column_m_,
		                     k.y * column_m_, column_m_) > far)
			spillColumn(c);
}

void TreeLayer::spillColumn(Column& c)
{
	switch (c.stem.spill(*spill_))
	{
		case SortedVoxels::SpillWrite::appended:
			stats_.spill_runs_appended++;
			break;
		case SortedVoxels::SpillWrite::merged:
			stats_.spill_runs_merged++;
			break;
		default:
			break;
	}
}

size_t TreeLayer::spilledBytes() const
{
	size_t n = 0;
	for (const auto& [k, c] : cols_) n += c.stem.spilledBytes();
	return n;
}

std::vector<ColumnKey> TreeLayer::columns() const
{
	std::vector<ColumnKey> out;
	for (const auto& [k, c] : cols_) out.push_back(k);
	std::sort(out.begin(), out.end());
	return out;
}

ColumnKey TreeLayer::columnOf(double x, double y) const
{
	return {int32_t(std::floor(x / column_m_)),
	        int32_t(std::floor(y / column_m_))};
}

TreeLayer::Column& TreeLayer::column(const ColumnKey& k)
{
	auto it = cols_.find(k);
	if (it == cols_.end())
	{
		Column c;
		c.stem = SortedVoxels(o_.layer_voxel_m);
		it = cols_.emplace(k, std::move(c)).first;
	}
	return it->second;
}

void TreeLayer::addScan(const std::vector<Eigen::Vector3f>& pts,
                        const Eigen::Vector3d& sensor, double time_s)
{
	if (released_)
		throw std::logic_error(
		    "TreeLayer::addScan after releaseStemVoxels (end of the run)");
	const auto t0 = std::chrono::steady_clock::now();
	const CpuTally cpu(stats_.cpu_ms), store_cpu(stats_.store_cpu_ms);
	stats_.scans++;
	if (!std::isfinite(time_s)) time_s = 0.1 * double(stats_.scans - 1);
	if (!std::isfinite(t0_s_)) t0_s_ = time_s;
	const float t_rel = float(time_s - t0_s_);
	const float max_r2 = float(o_.layer_max_range_m * o_.layer_max_range_m);
	const float inv_g = float(1.0 / o_.layer_ground_cell_m);
	const Eigen::Vector2f s2 = sensor.head<2>().cast<float>();
	// Pass 1: lowest point per ground cell (the scan's own ground counts
	// before its points are tested against it). The scan's cells first, in
	// a square grid around the sensor (an array, no hashing): then one
	// lookup per cell into its column's store instead of one per point
	// (the per-point lookups were a quarter of the store's CPU). A cell
	// belongs to the column of its centre, and so do its points.
	const double cell_m = o_.layer_ground_cell_m;
	const int half = int(std::ceil(o_.layer_max_range_m / cell_m)) + 2;
	const int side = 2 * half + 1;
	const int64_t ox = int64_t(std::floor(sensor.x() * inv_g)) - half,
	              oy = int64_t(std::floor(sensor.y() * inv_g)) - half;
	ScanCells& sc = scan_cells_;
	sc.lowest_of_cell.resize(size_t(side) * side, -1);
	sc.cell_of_point.assign(pts.size(), -1);
	sc.touched.clear();
	for (size_t i = 0; i < pts.size(); i++)
	{
		const auto& p = pts[i];
		if (!p.allFinite() || (p.head<2>() - s2).squaredNorm() > max_r2)
			continue;
		const int64_t lx = core::floorToInt(p.x() * inv_g) - ox,
		              ly = core::floorToInt(p.y() * inv_g) - oy;
		if (lx < 0 || ly < 0 || lx >= side || ly >= side) continue;
		const int32_t c = int32_t(lx + side * ly);
		sc.cell_of_point[i] = c;
		int32_t& low = sc.lowest_of_cell[size_t(c)];
		if (low < 0)
			low = int32_t(i), sc.touched.push_back(c);
		else if (p.z() < pts[size_t(low)].z())
			low = int32_t(i);
	}
	// Merged into the columns' stores; each cell's column and lowest height
	// kept for pass 2.
	sc.column_of_cell.resize(sc.lowest_of_cell.size());
	sc.low_z.resize(sc.lowest_of_cell.size());
	sc.tag_z.resize(sc.lowest_of_cell.size());
	ColumnKey last_key{INT32_MIN, INT32_MIN};
	Column* last_col = nullptr;
	for (const int32_t c : sc.touched)
	{
		const int64_t gx = ox + c % side, gy = oy + c / side;
		const ColumnKey ck =
		    columnOf((double(gx) + 0.5) * cell_m, (double(gy) + 0.5) * cell_m);
		if (!last_col || !(ck == last_key))
			last_col = &column(ck), last_key = ck;
		const Eigen::Vector3f& p = pts[size_t(sc.lowest_of_cell[size_t(c)])];
		bool added = false;
		Eigen::Vector3f& low =
		    last_col->lowest.tryEmplace(core::packCellKey(gx, gy, 0), &added);
		if (added || p.z() < low.z()) low = p;
		sc.column_of_cell[size_t(c)] = last_col;
		sc.low_z[size_t(c)] = low.z();
		sc.lowest_of_cell[size_t(c)] = -1;  // the grid is clean for next scan
	}
	// The time segments' height reference: the lowest point within
	// kTagReach cells. A big stem covers whole ground cells whose lowest
	// point is on the stem itself (the ground under it is never seen, and
	// shrubs may hide its foot): measured from there, its breast height
	// fell below the tagged band, its points there were merged across
	// passes and its ring blurred (58-minute run: stems of 56 and 62 cm
	// read 6 and 16 cm too large). The ground next to it is seen.
	// The square's minimum as two 1D ones: along the rows (each touched
	// cell spreads its height), then down the columns at the touched cells
	// (the 5 x 5 scan of every touched cell was a third of addScan).
	constexpr int kTagReach = 2;  // cells: 1 m at 0.5 m cells
	sc.row_min.assign(sc.lowest_of_cell.size(),
	                  std::numeric_limits<float>::infinity());
	for (const int32_t c : sc.touched)
	{
		const int cx = c % side, cy = c / side;
		const float z = sc.low_z[size_t(c)];
		float* row = sc.row_min.data() + size_t(side) * size_t(cy);
		for (int x = std::max(0, cx - kTagReach);
		     x <= std::min(side - 1, cx + kTagReach); x++)
			row[x] = std::min(row[x], z);
	}
	for (const int32_t c : sc.touched)
	{
		const int cx = c % side, cy = c / side;
		float z = sc.low_z[size_t(c)];
		for (int y = std::max(0, cy - kTagReach);
		     y <= std::min(side - 1, cy + kTagReach); y++)
			z = std::min(z, sc.row_min[size_t(cx + side * y)]);
		sc.tag_z[size_t(c)] = z;
	}
	// Pass 2: the stem band above the lowest point of the cell so far;
	// near breast height (above the lowest point within kTagReach cells)
	// tagged with the scan's time segment (the minimum is above the ground
	// until the ground is seen: a wide band).
	// Tag: time segment << 2 | range class (never 0); 0: not kept apart.
	const bool tagged = o_.dbh_segment_scans > 0;
	// (16 bits with the range class: segments past 16383, i.e. 45 hours
	// of 10 Hz scans in 100-scan segments, share the last one.)
	const uint32_t segment =
	    tagged ? uint32_t(std::min<uint64_t>(
	                 1 + (stats_.scans - 1) / uint64_t(o_.dbh_segment_scans),
	                 16383))
	           : 0;
	auto tag = [&](const Eigen::Vector3f& p)
	{
		const double r = (p.head<2>() - s2).norm();
		const uint32_t c =
		    o_.dbh_range_step_m > 0
		        ? uint32_t(std::min(3.0, std::floor(r / o_.dbh_range_step_m)))
		        : 0;
		return (segment << 2) | c;
	};
	const double seg_lo = o_.dbh_height_m - o_.dbh_segment_band_half_m - 0.5,
	             seg_hi = o_.dbh_height_m + o_.dbh_segment_band_half_m + 0.5;
	for (size_t i = 0; i < pts.size(); i++)
	{
		const int32_t c = sc.cell_of_point[i];
		if (c < 0) continue;
		Column* col = sc.column_of_cell[size_t(c)];
		const float low_z = sc.low_z[size_t(c)];
		const float h = pts[i].z() - low_z;
		if (h < o_.layer_min_hag_m || h > o_.layer_max_hag_m) continue;
		const float h_tag = pts[i].z() - sc.tag_z[size_t(c)];
		col->dirty = true;
		const Eigen::Vector3f d = pts[i] - sensor.cast<float>();
		const float n = d.norm();
		col->stem.add(
		    pts[i], n > 0 ? Eigen::Vector3f(d / n) : Eigen::Vector3f::Zero(),
		    tagged && h_tag >= seg_lo && h_tag <= seg_hi ? tag(pts[i]) : 0,
		    t_rel, pass_);
	}
	stats_.stored_voxels = 0;
	for (auto& [k, c] : cols_)
	{
		c.stem.compact(kMaxPending);
		stats_.stored_voxels += c.stem.size();
	}
	stats_.store_ms += msSince(t0);
}

size_t TreeLayer::update(const Eigen::Vector3d& sensor, map::CForestMap& map)
{
	const CpuTally cpu(stats_.cpu_ms);
	std::vector<ColumnKey> due;
	for (auto& [k, c] : cols_)
		if (detect_during_run_ && c.dirty &&
		    distanceToSquare(sensor.x(), sensor.y(), k.x * column_m_,
		                     k.y * column_m_,
		                     column_m_) > o_.layer_complete_distance_m)
		{
			// Its growth on voxels: the buffered points are one each.
			c.stem.compact();
			if (dueInRun(c)) due.push_back(k);
		}
	if (!due.empty()) compactAll();
	for (const auto& k : due)
	{
		stats_.detections_in_run++;
		if (cols_.at(k).detected) stats_.redetections_in_run++;
		detectColumn(k, map);
	}
	if (!due.empty()) publish(map);
	spillFar(sensor);
	return due.size();
}

size_t TreeLayer::finish(map::CForestMap& map)
{
	const double cpu_before_ms = stats_.cpu_ms;
	const size_t n = detectAllDirty(map);
	stats_.finish_cpu_ms += stats_.cpu_ms - cpu_before_ms;
	return n;
}

size_t TreeLayer::detectAllDirty(map::CForestMap& map)
{
	const CpuTally cpu(stats_.cpu_ms);
	std::vector<ColumnKey> due;
	for (const auto& [k, c] : cols_)
		if (c.dirty) due.push_back(k);
	// Deterministic order (ids are given in detection order).
	std::sort(due.begin(), due.end());
	// The end of the run detects every column (layer_detect_during_run
	// false) with the mapping thread idle: two columns at once, unless the
	// two together would hold more than kTwoAtOnceVoxels (each detection
	// reads its column and its neighbours' margins). The trees are found
	// in any order, then given their ids in `due` order: the same as one
	// at a time.
	compactAll();
	std::vector<std::vector<map::TreeRecord>> found(due.size());
	std::vector<double> ms(due.size());
	std::mutex mtx;
	std::condition_variable freed;
	size_t next = 0, running = 0, running_voxels = 0;
	std::exception_ptr error;
	auto work = [&]
	{
		std::unique_lock<std::mutex> lock(mtx);
		while (next < due.size() && !error)
		{
			const size_t i = next;
			const size_t w = cols_.at(due[i]).stem.size();
			if (running > 0 && running_voxels + w > kTwoAtOnceVoxels)
			{
				freed.wait(lock);
				continue;
			}
			next++, running++, running_voxels += w;
			lock.unlock();
			try
			{
				const auto t0 = std::chrono::steady_clock::now();
				found[i] = findTrees(due[i], map);
				ms[i] = msSince(t0);
				columnScratch().trim(kKeptScratchPoints);
			}
			catch (...)
			{
				const std::lock_guard<std::mutex> g(mtx);
				error = std::current_exception();
			}
			lock.lock();
			running--, running_voxels -= w;
			freed.notify_all();
		}
	};
	{
		std::optional<SecondThread> second;
		if (due.size() > 1) second.emplace(work, stats_.cpu_ms);
		work();
	}
	// The buffers of this thread (the second thread's went with it): the
	// robot run kept 165 MB of them through the output writing.
	columnScratch() = ColumnScratch{};
	SortedVoxels::freeReadBuffers();
	if (error) std::rethrow_exception(error);
	for (size_t i = 0; i < due.size(); i++)
	{
		giveTrees(due[i], std::move(found[i]), ms[i]);
		// The end of the run holds no more than the columns being read.
		if (spill_) spillColumn(cols_.at(due[i]));
	}
	stats_.stored_voxels = 0;  // spilled and added voxels merged now
	for (const auto& [k, c] : cols_) stats_.stored_voxels += c.stem.size();
	publish(map);
	return due.size();
}

void TreeLayer::compactAll()
{
	for (auto& [k, c] : cols_) c.stem.compact();
}

void TreeLayer::detectColumn(const ColumnKey& k, const map::CForestMap& map)
{
	const auto t0 = std::chrono::steady_clock::now();
	auto found = findTrees(k, map);
	columnScratch().trim(kKeptScratchPoints);
	giveTrees(k, std::move(found), msSince(t0));
}

std::vector<map::TreeRecord> TreeLayer::findTrees(
    const ColumnKey& k, const map::CForestMap& map) const
{
	const double x0 = k.x * column_m_, y0 = k.y * column_m_;
	const double margin = o_.layer_margin_m;
	// The terrain needs a wider margin than the stems: the DTM filter looks
	// dtm_window_cells around every cell.
	const double ground_margin =
	    margin + (o_.dtm_window_cells + 1) * o_.dtm_cell_m;
	auto inside = [&](double x, double y, double m)
	{
		return x >= x0 - m && x < x0 + column_m_ + m && y >= y0 - m &&
		       y < y0 + column_m_ + m;
	};
	// The buffers stay with the thread (cleared, capacity kept): a column's
	// tens of MB allocated afresh per detection came back as page faults,
	// a fifth of the detection's CPU in the kernel.
	ColumnScratch& s = columnScratch();
	s.clear();
	ColumnInput& in = s.in;
	in.x0 = x0, in.y0 = y0, in.size_m = column_m_;
	auto& pts = in.pts;
	auto& ground = in.ground;
	auto& dirs = in.dirs;    // per point of pts; 0: unknown
	auto& times = in.times;  // per point of pts: mean time [s]
	auto& seg = in.seg;      // breast-height voxels per time segment
	{
		// The column and a margin (~1/4 more): grown by doubling, a big
		// column held old and new arrays at once.
		const size_t expect = cols_.at(k).stem.size() * 5 / 4;
		pts.reserve(expect), dirs.reserve(expect), times.reserve(expect);
	}
	for (int dx = -1; dx <= 1; dx++)
		for (int dy = -1; dy <= 1; dy++)
		{
			const auto it = cols_.find({k.x + dx, k.y + dy});
			if (it == cols_.end()) continue;
			it->second.lowest.forEach(
			    [&](uint64_t, const Eigen::Vector3f& p)
			    {
				    if (inside(p.x(), p.y(), ground_margin))
					    ground.push_back(p.cast<double>());
			    });
			SortedVoxels& copy =
			    SortedVoxels::readBuffers().copy;  // buffers kept, as s's
			const auto& stem = readable(
			    it->second, copy,
			    Eigen::Vector2f(float(x0 - margin), float(y0 - margin)),
			    Eigen::Vector2f(float(x0 + column_m_ + margin),
			                    float(y0 + column_m_ + margin)));
			stem.forEach(
			    [&](const Eigen::Vector3f& c, const Eigen::Vector3f& d, float t)
			    {
				    if (inside(c.x(), c.y(), margin))
					    pts.push_back(c.cast<double>()), dirs.push_back(d),
					        times.push_back(t);
			    },
			    [&](const Eigen::Vector3f& c, const Eigen::Vector3f& d,
			        uint32_t s)
			    {
				    if (inside(c.x(), c.y(), margin))
				    {
					    seg.pts.push_back(c.cast<double>());
					    seg.dirs.push_back(d);
					    seg.segment.push_back(s >> 2);
					    seg.range_class.push_back(uint8_t(s & 3));
				    }
			    });
			// Margin strips reuse the buffers; a whole column's copy goes.
			SortedVoxels::trimReadBuffers(kKeptReadVoxels);
		}
	std::vector<map::TreeRecord> found;
	if (!ground.empty() && !pts.empty())
	{
		const TerrainModel dtm = buildDtm(ground, o_);
		// Tree tops: the map's own voxels above the stem band, from the
		// submaps over this column only (their squares are the columns):
		// gathering the neighbours' too, for the top of a stem within
		// top_search_radius_m of the border, was a quarter of the detection
		// time; such a top is searched on this column's side only.
		const double band_top = o_.slice_max_m + 0.5 * o_.slice_thickness_m;
		const int sx = int(std::floor(x0 / map.options().submap_size_m + 0.5));
		const int sy = int(std::floor(y0 / map.options().submap_size_m + 0.5));
		auto& above = s.above;
		for (const auto& [key, sm] : map.submaps())
		{
			if (key.x != sx || key.y != sy) continue;
			sm.edge.appendCentroids(above);
			sm.planar.appendCentroids(above);
		}
		for (const auto& c : above)
			if (inside(c.x(), c.y(), margin))
			{
				const Eigen::Vector3d p = c.cast<double>();
				if (dtm.heightAboveGround(p) > band_top)
					pts.push_back(p), dirs.push_back(Eigen::Vector3f::Zero()),
					    times.push_back(0.0f);
			}
		if (!o_.layer_dump_dir.empty())
			writeColumnInput(o_.layer_dump_dir + "/column_" +
			                     std::to_string(k.x) + "_" +
			                     std::to_string(k.y) + ".bin",
			                 in);
		found = detectColumnTrees(in, dtm, o_);
	}
	return found;
}

void TreeLayer::giveTrees(const ColumnKey& k,
                          std::vector<map::TreeRecord> found, double ms)
{
	Column& col = cols_.at(k);
	col.dirty = false;
	col.detected = true;
	col.detected_voxels = col.stem.size();
	// Keep the ids of trees seen before (online users refer to them).
	std::vector<char> reused(col.trees.size(), 0);
	for (auto& t : found)
	{
		t.id = 0;
		for (size_t j = 0; j < col.trees.size(); j++)
		{
			const auto& old = col.trees[j];
			if (!reused[j] &&
			    std::hypot(old.x - t.x, old.y - t.y) <
			        std::max(0.5 * std::max(old.dbh_m, t.dbh_m), 0.1))
			{
				t.id = old.id;
				reused[j] = 1;
				break;
			}
		}
		if (t.id == 0) t.id = next_id_++;
	}
	col.trees = std::move(found);
	stats_.detections++;
	stats_.detect_ms += ms;
	stats_.detect_ms_each.push_back(ms);
}

void TreeLayer::publish(map::CForestMap& map) const
{
	// A stem on a column border can be found from both sides with its centre
	// estimated on either side: keep the better-confirmed one.
	std::vector<map::TreeRecord> all;
	for (const auto& [k, c] : cols_)
		for (map::TreeRecord t : c.trees)
		{
			if (c.shown.matrix() != Eigen::Matrix4d::Identity())
			{
				const Eigen::Vector3d q =
				    c.shown * Eigen::Vector3d(t.x, t.y, t.z_ground);
				t.x = q.x(), t.y = q.y(), t.z_ground = q.z();
			}
			all.push_back(t);
		}
	std::sort(all.begin(), all.end(),
	          [](const map::TreeRecord& a, const map::TreeRecord& b) {
		          return a.n_slices != b.n_slices ? a.n_slices > b.n_slices
		                                          : a.id < b.id;
	          });
	std::vector<map::TreeRecord> kept;
	for (const auto& t : all)
	{
		bool dup = false;
		for (const auto& u : kept)
			if (std::hypot(u.x - t.x, u.y - t.y) <
			    0.5 * std::max(u.dbh_m, t.dbh_m) + 0.05)
				dup = true;
		if (!dup) kept.push_back(t);
	}
	std::sort(kept.begin(), kept.end(),
	          [](const map::TreeRecord& a, const map::TreeRecord& b)
	          { return a.id < b.id; });
	map.setTrees(std::move(kept));
}

void TreeLayer::startPass()
{
	pass_++;
}

size_t TreeLayer::correct(
    const AtTime& at_time,
    const std::function<Eigen::Isometry3d(const ColumnKey&)>& of_column,
    map::CForestMap& map, bool in_run)
{
	CorrectionSteps steps = beginCorrection(in_run);
	correctStep(steps, at_time, of_column, map,
	            std::numeric_limits<size_t>::max());
	return steps.redetect;
}

TreeLayer::CorrectionSteps TreeLayer::beginCorrection(
    bool in_run, std::vector<ColumnKey> keys, uint32_t version) const
{
	if (released_)
		throw std::logic_error("TreeLayer::correct after releaseStemVoxels");
	CorrectionSteps steps;
	if (keys.empty())
		steps.keys = columns();
	else
	{
		// Sorted, existing columns only (the order of the steps).
		keys.erase(
		    std::remove_if(keys.begin(), keys.end(),
		                   [&](const ColumnKey& k) { return !cols_.count(k); }),
		    keys.end());
		std::sort(keys.begin(), keys.end());
		steps.keys = std::move(keys);
	}
	steps.in_run = in_run;
	steps.version = version;
	// In the run the passes started from now on are in the newer frame;
	// at the end every pass is moved.
	steps.last_pass = in_run ? pass_ : UINT32_MAX;
	return steps;
}

bool TreeLayer::correctStep(
    CorrectionSteps& steps, const AtTime& at_time,
    const std::function<Eigen::Isometry3d(const ColumnKey&)>& of_column,
    map::CForestMap& map, size_t max_voxels)
{
	if (released_)
		throw std::logic_error("TreeLayer::correct after releaseStemVoxels");
	const auto started = std::chrono::steady_clock::now();
	double cpu_ms = 0;  // both threads, added to cpu_ms and correct_cpu_ms
	const double t0 = std::isfinite(t0_s_) ? t0_s_ : 0.0;
	const float rigid_m = float(0.5 * o_.layer_voxel_m);
	const std::vector<ColumnKey>& keys = steps.keys;
	// Columns are moved two at a time (the end of a run waited seconds for
	// this on one core), unless the two would hold more than
	// kTwoAtOnceVoxels; the spill file and the counts are shared (mtx).
	// The step ends once its columns held max_voxels: taken in key order
	// under the lock, so the same columns whatever the thread timing.
	size_t running = 0, running_voxels = 0;
	const size_t moved_before = steps.moved_voxels;
	std::mutex mtx;
	std::condition_variable freed;
	std::exception_ptr error;
	auto work = [&]
	{
		std::unique_lock<std::mutex> lock(mtx);
		while (steps.next < keys.size() &&
		       steps.moved_voxels - moved_before < max_voxels && !error)
		{
			Column& c = cols_.at(keys[steps.next]);
			const size_t w = c.stem.size();
			if (running > 0 && running_voxels + w > kTwoAtOnceVoxels)
			{
				freed.wait(lock);
				continue;
			}
			const ColumnKey k = keys[steps.next++];
			running++, running_voxels += w;
			steps.moved_voxels += std::max<size_t>(w, 1);
			lock.unlock();
			try
			{
				const Eigen::Isometry3d T = of_column(k);
				SortedVoxels& stem = resident(c);  // reads only
				const size_t before = stem.size();
				const float worst = stem.transformByTime(
				    [&, v = c.version](float t)
				    { return at_time(v, t0 + double(t)); },
				    T.cast<float>(), steps.in_run, steps.last_pass);
				if (steps.in_run) c.version = steps.version;
				moveGroundAndTrees(c, T);
				c.shown = Eigen::Isometry3d::Identity();
				stem.compact();
				lock.lock();
				stats_.stored_voxels += stem.size();
				stats_.stored_voxels -= before;
				// Passes that disagreed (or points off the column's
				// correction by more than half a voxel): the stems were
				// found on blurred rings.
				if (worst > rigid_m)
				{
					c.dirty = true;
					steps.redetect++;
				}
				// finish() reads back the columns it detects and their
				// neighbours only: the corrected whole does not stay in
				// memory at once.
				if (spill_) spillColumn(c);
			}
			catch (...)
			{
				if (!lock.owns_lock()) lock.lock();
				error = std::current_exception();
			}
			running--, running_voxels -= w;
			freed.notify_all();
		}
	};
	{
		const CpuTally cpu(cpu_ms);
		std::optional<SecondThread> second;
		if (keys.size() - steps.next > 1) second.emplace(work, cpu_ms);
		work();
	}
	if (!error && steps.done())
	{
		const CpuTally cpu(cpu_ms);
		// At the end of the run every pass is now one; in the run the
		// passes after last_pass go on (their frame is the newer one).
		if (!steps.in_run) pass_ = 0;
		publish(map);
	}
	stats_.cpu_ms += cpu_ms;
	stats_.correct_cpu_ms += cpu_ms;
	stats_.correct_ms += msSince(started);
	if (error) std::rethrow_exception(error);
	return steps.done();
}

void TreeLayer::moveGroundAndTrees(Column& c, const Eigen::Isometry3d& T)
{
	const Eigen::Isometry3f Tf = T.cast<float>();
	const float inv_g = float(1.0 / o_.layer_ground_cell_m);
	decltype(c.lowest) lowest;
	c.lowest.forEach(
	    [&](uint64_t, const Eigen::Vector3f& p)
	    {
		    const Eigen::Vector3f q = Tf * p;
		    bool added = false;
		    Eigen::Vector3f& low = lowest.tryEmplace(
		        core::packCellKey(core::floorToInt(q.x() * inv_g),
		                          core::floorToInt(q.y() * inv_g), 0),
		        &added);
		    if (added || q.z() < low.z()) low = q;
	    });
	std::swap(c.lowest, lowest);
	for (auto& t : c.trees)
	{
		const Eigen::Vector3d q = T * Eigen::Vector3d(t.x, t.y, t.z_ground);
		t.x = q.x(), t.y = q.y(), t.z_ground = q.z();
	}
}

void TreeLayer::showColumns(
    const std::vector<std::pair<ColumnKey, Eigen::Isometry3d>>& shown,
    map::CForestMap& map)
{
	for (const auto& [k, T] : shown)
	{
		const auto it = cols_.find(k);
		if (it != cols_.end()) it->second.shown = T;
	}
	publish(map);
}

void TreeLayer::releaseStemVoxels()
{
	for (auto& [k, c] : cols_) c.stem.release();
	spill_.reset();  // the scratch file goes with its last reader
	stats_.released_voxels = stats_.stored_voxels;
	stats_.stored_voxels = 0;
	released_ = true;
}

void TreeLayer::transformColumn(const ColumnKey& k, const Eigen::Isometry3d& T,
                                map::CForestMap& map)
{
	const auto it = cols_.find(k);
	if (it == cols_.end()) return;
	Column& c = it->second;
	const CpuTally cpu(stats_.cpu_ms);
	stats_.stored_voxels -= c.stem.size();
	resident(c).transform(T.cast<float>());
	stats_.stored_voxels += c.stem.size();
	c.dirty = true;  // detected again when due
	moveGroundAndTrees(c, T);
	publish(map);
}

double TreeLayer::density(const Column& c)
{
	return double(c.stem.size()) / double(std::max<size_t>(1, c.lowest.size()));
}

std::vector<ColumnKey> TreeLayer::takePiledUpColumns(
    double growth, const Eigen::Vector3d& sensor)
{
	std::vector<ColumnKey> out;
	for (auto& [k, c] : cols_)
	{
		if (distanceToSquare(sensor.x(), sensor.y(), k.x * column_m_,
		                     k.y * column_m_,
		                     column_m_) <= o_.layer_max_range_m)
			continue;
		const double d = density(c);
		if (c.pile_density <= 0)
			c.pile_density = d;
		else if (d >= growth * c.pile_density)
			out.push_back(k), c.pile_density = d;
	}
	std::sort(out.begin(), out.end());
	return out;
}

uint32_t TreeLayer::mergeVersion(const ColumnKey& k) const
{
	const auto it = cols_.find(k);
	return it == cols_.end() ? 0 : it->second.version;
}

size_t TreeLayer::groundCells() const
{
	size_t n = 0;
	for (const auto& [k, c] : cols_) n += c.lowest.size();
	return n;
}

size_t TreeLayer::memoryBytes() const
{
	size_t n = core::hashMapBytes(cols_);
	for (const auto& [k, c] : cols_)
		n += c.lowest.memoryBytes() + c.stem.memoryBytes() +
		     core::vectorBytes(c.trees);
	return n;
}

std::vector<Eigen::Vector3f> TreeLayer::stemPoints(const ColumnKey& k) const
{
	std::vector<Eigen::Vector3f> out;
	const auto it = cols_.find(k);
	if (it == cols_.end()) return out;
	auto& stem =
	    const_cast<TreeLayer*>(this)->resident(const_cast<Column&>(it->second));
	stem.compact();
	stem.forEach([&](const Eigen::Vector3f& c, const Eigen::Vector3f&, float)
	             { out.push_back(c); });
	return out;
}

}  // namespace forest_slam::trees
