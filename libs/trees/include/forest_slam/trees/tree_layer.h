#pragma once
// Incremental tree layer of a SLAM run (issue 7): deskewed scans in the map
// frame feed a stem-band point store tied to the map's submap columns; when
// the sensor has moved away from a column (or at the end of the run) the
// stems of that column are detected on its accumulated points and the
// CForestMap tree layer is updated, so trees are available during an online
// run. See doc/trees.md "Tree layer of a SLAM run".
//
// Store per column (the map's submap_size_m squares in x, y):
//  - the lowest point of every layer_ground_cell_m cell: the terrain model
//    (buildDtm on these points) at detection time;
//  - a voxel cloud (layer_voxel_m, exact centroids) of the points between
//    layer_min_hag_m and layer_max_hag_m above the lowest point of their
//    ground cell so far: the stem band, fine enough for the DBH fit, which
//    the map's 0.2 m / 0.4 m feature voxels are not.
// Tree tops come from the map's own voxel clouds above the stem band.
#include <forest_slam/core/fast_math.h>
#include <forest_slam/core/flat_hash_map.h>
#include <forest_slam/core/spill_file.h>
#include <forest_slam/map/forest_map.h>
#include <forest_slam/trees/tree_options.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <type_traits>
#include <unordered_map>
#include <vector>

namespace forest_slam::trees
{
/** A submap column: the map's submap key without z. */
struct ColumnKey
{
	int32_t x = 0, y = 0;
	bool operator==(const ColumnKey& o) const { return x == o.x && y == o.y; }
	/** x, then y: the columns' deterministic order. */
	bool operator<(const ColumnKey& o) const
	{
		return x != o.x ? x < o.x : y < o.y;
	}
};
struct ColumnKeyHash
{
	size_t operator()(const ColumnKey& k) const
	{
		return (static_cast<size_t>(static_cast<uint32_t>(k.x)) << 32) ^
		       static_cast<uint32_t>(k.y);
	}
};

struct TreeLayerStats
{
	uint64_t scans = 0;
	uint64_t detections = 0;  ///< column detections run
	/** Of detections: during the run (update()), and of those, columns
	 * detected before (revisits grown by layer_redetect_growth). */
	uint64_t detections_in_run = 0;
	uint64_t redetections_in_run = 0;
	double store_ms = 0;   ///< total time adding scans
	double detect_ms = 0;  ///< total time detecting
	/** Wall time of correct() (loop corrections: in the run and at its
	 * end; two columns at a time), detections it triggered included. */
	double correct_ms = 0;
	/** CPU time of all the layer's calls, on every thread they use
	 * (thread clocks): the share of the process CPU it costs. */
	double cpu_ms = 0;
	/** Of cpu_ms: finish(), the detection of every column left at the end
	 * of the run (a recorded run detects its stems there only). The rest
	 * is the updates: storing scans, spilling, corrections, detections
	 * during the run. */
	double finish_cpu_ms = 0;
	/** Of cpu_ms: storing scans (addScan), and moving the stored voxels
	 * with loop corrections (in-run merges and the final correction). */
	double store_cpu_ms = 0;
	double correct_cpu_ms = 0;
	/** Of cpu_ms: writing the columns out of the sensor's reach to the
	 * spill file (a revisited column is merged with its copy on disk). */
	double spill_cpu_ms = 0;
	/** Spills of a revisited column: its new voxels appended to the disk
	 * copy as a run of their own (all of later passes), or merged with
	 * the copy (some of a pass on disk, or the runs' limit reached). */
	uint64_t spill_runs_appended = 0;
	uint64_t spill_runs_merged = 0;
	std::vector<double> detect_ms_each;  ///< per column detection
	size_t stored_voxels = 0;            ///< stem-band voxels now
	/** Stem-band voxels when releaseStemVoxels() freed them (0 before). */
	size_t released_voxels = 0;
};

class TreeLayer
{
   public:
	/** Voxels per chunk when a column spilled again after a revisit is
	 * merged with its copy on disk (memory of that merge: two chunks).
	 * Tests set it small, to cross the chunk borders. */
	inline static size_t spill_merge_chunk_voxels = size_t(1) << 18;
	/** Runs a spilled column may hold on disk before they are merged into
	 * one (at most 4; tests set fewer). */
	inline static int spill_max_runs = 4;

	/** `detect_during_run`: update() detects the columns the sensor has
	 * left (trees during the run); false: only finish() detects, once per
	 * column, and update() only spills (TreeOptions::detectDuringRun). */
	TreeLayer(const TreeOptions& o, double column_size_m,
	          bool detect_during_run = true);

	/** Adds the points (map frame, gravity-aligned, deskewed) of one scan
	 * taken from `sensor` (map frame) at `time_s` (NaN: 0.1 s per scan
	 * added, a 10 Hz lidar). */
	void addScan(const std::vector<Eigen::Vector3f>& pts,
	             const Eigen::Vector3d& sensor,
	             double time_s = std::numeric_limits<double>::quiet_NaN());

	/** Detects the stems of every column with new points whose square is
	 * farther than layer_complete_distance_m from `sensor`, and writes the
	 * tree layer into `map` (not with detect_during_run false). Spills
	 * the columns out of the sensor's reach. Returns the number of columns
	 * detected. */
	size_t update(const Eigen::Vector3d& sensor, map::CForestMap& map);
	/** End of the run: detects every column with new points. */
	size_t finish(map::CForestMap& map);

	/** A loop correction moved the map frame during the run: the points
	 * added from now on are a new pass, never merged into the voxels of
	 * earlier passes, so that correct() can move each with its own
	 * correction. (Merged, the passes of a stem a few cm apart made two
	 * rings: the robot run's layer missed 17 % of the stems the same layer
	 * finds with GT poses.) */
	void startPass();
	/** End of a run with loop closure, before finish(): the final
	 * trajectory moves every stem-band voxel with `at_time(t)`, the
	 * correction of the scan taken at the voxel's mean time t (absolute
	 * [s]), and each column's ground cells and trees with
	 * `of_column(key)`. A column whose voxels all move within
	 * layer_voxel_m / 2 of its own correction moves rigidly and keeps its
	 * trees; the others are detected again at finish(). Returns the number
	 * of those.
	 * `in_run`: a merge during the run (the passes of a long run would
	 * otherwise pile up, one more per lap, in every column): the merged
	 * voxel keeps the time of the pass that saw it most, so that a later
	 * correction looks up a scan that was there (the mean time of passes
	 * minutes apart is a scan elsewhere); the columns to detect again are
	 * detected when due, as in update(). */
	/** `at_time(version, t)`: the correction of the scan at time t for a
	 * column whose voxels were last merged by the in-run merge numbered
	 * `version` (beginCorrection; 0: never merged, as mapped). */
	using AtTime =
	    std::function<Eigen::Isometry3f(uint32_t version, double t_s)>;
	size_t correct(
	    const AtTime& at_time,
	    const std::function<Eigen::Isometry3d(const ColumnKey&)>& of_column,
	    map::CForestMap& map, bool in_run = false);

	/** correct() a few columns at a time: an in-run merge in steps, so
	 * that the scans mapped meanwhile are not held up (the robot run's
	 * merge took 5–6 s on the map thread in one piece). The passes started
	 * up to beginCorrection() are merged (pass 0); the later ones, whose
	 * scans are in the newer frame, are left as they are, so points can
	 * be added and startPass() called between the steps. */
	struct CorrectionSteps
	{
		std::vector<ColumnKey> keys;  ///< the columns to move
		size_t next = 0;              ///< first of keys not moved yet
		uint32_t last_pass = 0;       ///< passes merged: 0..last_pass
		bool in_run = true;
		/** In the run: the merge's number, which the columns moved take
		 * (their voxels are then where this merge's estimate put them). */
		uint32_t version = 0;
		size_t redetect = 0;  ///< columns whose passes disagreed so far
		/** Stem-band voxels the steps so far took (1 for an empty column). */
		size_t moved_voxels = 0;
		bool done() const { return next >= keys.size(); }
	};
	/** `keys`: the columns to move (empty: all); `version`: the in-run
	 * merge's number (> every earlier one), which they take. */
	CorrectionSteps beginCorrection(bool in_run,
	                                std::vector<ColumnKey> keys = {},
	                                uint32_t version = 0) const;
	/** Moves the next columns of `steps` (as correct()) until they held
	 * `max_voxels` stem-band voxels (at least one column); after the last
	 * one writes the tree layer into `map`. Returns steps.done(). */
	bool correctStep(
	    CorrectionSteps& steps, const AtTime& at_time,
	    const std::function<Eigen::Isometry3d(const ColumnKey&)>& of_column,
	    map::CForestMap& map, size_t max_voxels);

	/** End of a run, after finish(): frees the stem-band voxels (in memory
	 * and spilled; 1.2 GB at the end of the 7-minute handheld run, whose
	 * final loop correction had read every spilled column back). The trees
	 * and ground cells stay, transformColumn() then moves the trees only;
	 * addScan() afterwards throws std::logic_error. */
	void releaseStemVoxels();

	/** A loop correction during a live run, which moves the columns'
	 * voxels only at the next merge of the passes (correctStep): the trees
	 * of the columns in `shown` are published moved by their transform
	 * (from the frame their voxels are in to the newest estimate) until
	 * their voxels are moved. Writes the tree layer into `map`. */
	void showColumns(
	    const std::vector<std::pair<ColumnKey, Eigen::Isometry3d>>& shown,
	    map::CForestMap& map);

	/** Loop correction: moves the stored points and the trees of one
	 * column by `T` (map frame) and rewrites the tree layer of `map`. */
	void transformColumn(const ColumnKey& k, const Eigen::Isometry3d& T,
	                     map::CForestMap& map);

	ColumnKey columnOf(double x, double y) const;
	/** Every column holding points, sorted (deterministic order). */
	std::vector<ColumnKey> columns() const;
	double columnSize() const { return column_m_; }
	/** Whether update() detects stems during the run (the constructor's
	 * `detect_during_run`). */
	bool detectsDuringRun() const { return detect_during_run_; }
	/** Ground cells (layer_ground_cell_m squares) holding a lowest point:
	 * the area the layer has seen. */
	size_t groundCells() const;
	/** The columns where the passes piled up: stem-band voxels per ground
	 * cell at least `growth` times what they were when last returned here,
	 * or when first seen out of the reach of new points
	 * (layer_max_range_m from `sensor`), i.e. complete. The path coming
	 * back adds a pass's copy of the stems to the ground already seen; a
	 * column still being filled adds both. Columns within reach are left
	 * for later. The columns returned start again from their density now. */
	std::vector<ColumnKey> takePiledUpColumns(double growth,
	                                          const Eigen::Vector3d& sensor);
	/** The in-run merge that last moved column k (0: none; as mapped). */
	uint32_t mergeVersion(const ColumnKey& k) const;
	/** Stem-band points of a column (voxel centroids), for diagnostics. */
	std::vector<Eigen::Vector3f> stemPoints(const ColumnKey& k) const;
	const TreeLayerStats& stats() const { return stats_; }
	/** Heap bytes of the stored columns (estimate, core/memory.h). */
	size_t memoryBytes() const;
	/** Bytes of stem-band voxels now on disk. */
	size_t spilledBytes() const;
	/** Disk space the layer's scratch file takes (0 without one): old
	 * copies of rewritten columns are given back (SpillFile::discard). */
	size_t spillFileBytes() const
	{
		return spill_ ? spill_->allocatedBytes() : 0;
	}

   private:
	/** Stem-band voxels (exact centroids, like map::VoxelCloud) as a sorted
	 * array: scans are appended to a buffer that is merged in by sorting
	 * when it grows, so a scan costs a push_back per point instead of a
	 * hash lookup into millions of voxels. Each voxel also sums the unit
	 * viewing directions (sensor → point) of its points: the DBH fit models
	 * the range noise along the rays (refineCircleAlongRays). */
	class SortedVoxels
	{
	   public:
		explicit SortedVoxels(double voxel_m = 0.02) { setVoxelSize(voxel_m); }
		/** `segment`: the time segment of the point's scan, or 0 (merged
		 * with every segment's voxel of the cell). */
		void add(const Eigen::Vector3f& p, const Eigen::Vector3f& dir,
		         uint32_t segment = 0, float time = 0, uint32_t pass = 0)
		{
			// As a one-point voxel: compact() sorts the buffer in place.
			const uint64_t k = keyOf(p);
			pending_.push_back(
			    makeVoxel(k, p - centreOf(k), dir, 1, segment, time, pass));
		}
		/** Merges the buffer if it holds more than `max_pending` points
		 * (into the voxels in memory: a spilled set's new voxels). */
		void compact(size_t max_pending = 0);
		/** Voxels and buffered points (spilled: on disk plus those added
		 * since, which may share cells with them: an upper bound). */
		size_t size() const
		{
			return (spilled_ ? disk_count_ : 0) + voxels_.size() +
			       pending_.size();
		}
		/** Calls f(centroid, mean viewing direction (not normalised), mean
		 * time of the points) for every voxel, the time segments of a cell
		 * merged (compact() first); and seg(centroid, direction, segment)
		 * for every voxel of a segment != 0, if given. */
		template <class F, class S = std::nullptr_t>
		void forEach(F&& f, S&& seg = nullptr) const
		{
			for (size_t i = 0; i < voxels_.size();)
			{
				Eigen::Vector3f sum = Eigen::Vector3f::Zero(),
				                dir = Eigen::Vector3f::Zero();
				uint32_t count = 0;
				double t = 0;
				const uint64_t key = voxels_[i].key;
				for (; i < voxels_.size() && voxels_[i].key == key; i++)
				{
					const Voxel& v = voxels_[i];
					const float n = float(v.count);
					sum += offsetOf(v) * n, dir += dirOf(v) * n;
					count += v.count;
					t += double(v.time) * v.count;
					if constexpr (!std::is_same_v<std::decay_t<S>,
					                              std::nullptr_t>)
						if (v.segment != 0)
							seg(centroid(v), dirOf(v), v.segment);
				}
				f(Eigen::Vector3f(centreOf(key) + sum / float(count)),
				  Eigen::Vector3f(dir / float(count)), float(t / count));
			}
		}
		void transform(const Eigen::Isometry3f& T);
		/** Moves each voxel with `at(mean time)` and merges the passes
		 * (the merged time: weighted mean, or with `dominant_time` that of
		 * the pass with most points); the passes after `last_pass` stay
		 * where and as they are. Returns the largest distance between
		 * where a voxel went and where `T` would have put it. */
		float transformByTime(const std::function<Eigen::Isometry3f(float)>& at,
		                      const Eigen::Isometry3f& T,
		                      bool dominant_time = false,
		                      uint32_t last_pass = UINT32_MAX);
		/** Drops every voxel (and forgets a spilled set). */
		void release()
		{
			std::vector<Voxel>().swap(voxels_);
			std::vector<Voxel>().swap(pending_);
			spilled_ = false;
			changed_ = true;
			n_runs_ = 0;
			disk_count_ = 0;
		}
		/** What spill() wrote. */
		enum class SpillWrite
		{
			nothing,   ///< the copy on disk was up to date
			whole,     ///< the set, as one run
			appended,  ///< the voxels added since, as one more run
			merged     ///< the runs and the voxels added since, as one run
		};
		/** Moves the voxels to `f` (compact() first); a set read back and
		 * not changed since is not written again. Points added to a
		 * spilled set do not read it back: they are voxelized apart in
		 * memory and, on the next spill(), appended as a run of their own
		 * when all are of passes after those on disk (no voxel in common,
		 * so size() stays exact), else merged with the runs on disk. */
		SpillWrite spill(core::SpillFile& f);
		/** Reads spilled voxels back (merging those added since). */
		void reload(const core::SpillFile& f);
		/** Into `copy` (its buffers reused), the voxels whose cells are in
		 * the horizontal box [lo, hi] [m], for reading; the set stays as it
		 * is (spilled or not). A spilled set is read in chunks, and only
		 * over the run of keys whose x cells are in the box: the keys are
		 * sorted x first, so a neighbour's margin strip beside the column
		 * is a short run of the file. */
		void loadInto(const core::SpillFile* f, const Eigen::Vector2f& lo,
		              const Eigen::Vector2f& hi, SortedVoxels& copy) const;
		/** The calling thread's buffers of loadInto() and of the copies
		 * it fills (a column's worth, kept between detections), and their
		 * release. */
		struct ReadBuffers;
		static ReadBuffers& readBuffers();
		static void freeReadBuffers();
		/** Frees those buffers that hold more than `voxels`: a big
		 * column's copy would otherwise stay through the small ones (two
		 * threads detecting at once each kept their largest). */
		static void trimReadBuffers(size_t voxels);
		bool spilled() const { return spilled_; }
		size_t spilledBytes() const
		{
			return spilled_ ? disk_count_ * sizeof(Voxel) : 0;
		}
		size_t memoryBytes() const
		{
			return voxels_.capacity() * sizeof(Voxel) +
			       pending_.capacity() * sizeof(Voxel);
		}
		/** No points buffered (compact() has nothing to do). */
		bool compacted() const { return pending_.empty(); }
		/** Voxels (or points) held in memory. */
		size_t sizeInMemory() const { return voxels_.size() + pending_.size(); }

	   private:
		/** 32 bytes (48 with float sums: a third of the tree layer's
		 * sorting, merging and disk traffic went with the difference).
		 * Means, not sums, in 16-bit fixed point: the offset to 1/65534 of
		 * a voxel (0.3 µm at 2 cm), the direction to 3e-5; merging two
		 * rounds once, to half a step. */
		struct Voxel
		{
			/** Uninitialised: a vector grown for a disk read or a merge is
			 * written over whole, and zeroing it first (value-initialising
			 * an aggregate) was 1 % of a robot run's CPU. */
			Voxel() {}
			uint64_t key;
			int16_t offset[3];  ///< mean offset from the voxel centre
			int16_t dir[3];     ///< mean unit viewing direction
			uint32_t count;
			float time;  ///< mean time of the points [s since the first scan]
			uint16_t segment;  ///< time segment tag (0: none)
			uint16_t pass;     ///< TreeLayer::startPass count (saturated);
			                   ///< sorted by (key, pass, segment)
		};
		static constexpr float kDirScale = 32767.0f;
		static int16_t toFixed(float v)
		{
			return int16_t(
			    core::roundToLong(std::clamp(v, -32767.0f, 32767.0f)));
		}
		/** A voxel of `count` points with these means. */
		Voxel makeVoxel(uint64_t key, const Eigen::Vector3f& offset,
		                const Eigen::Vector3f& dir, uint32_t count,
		                uint32_t segment, float time, uint32_t pass) const
		{
			Voxel v;
			v.key = key;
			setOffset(v, offset);
			setDir(v, dir);
			v.count = count;
			v.time = time;
			v.segment = uint16_t(std::min<uint32_t>(segment, 0xffff));
			v.pass = uint16_t(std::min<uint32_t>(pass, 0xffff));
			return v;
		}
		void setOffset(Voxel& v, const Eigen::Vector3f& o) const
		{
			for (int i = 0; i < 3; i++)
				v.offset[i] = toFixed(o[i] * offset_scale_);
		}
		Eigen::Vector3f offsetOf(const Voxel& v) const
		{
			return Eigen::Vector3f(v.offset[0], v.offset[1], v.offset[2]) /
			       offset_scale_;
		}
		static void setDir(Voxel& v, const Eigen::Vector3f& d)
		{
			for (int i = 0; i < 3; i++) v.dir[i] = toFixed(d[i] * kDirScale);
		}
		static Eigen::Vector3f dirOf(const Voxel& v)
		{
			return Eigen::Vector3f(v.dir[0], v.dir[1], v.dir[2]) / kDirScale;
		}
		/** The voxel size and the offsets' fixed-point scale, together (a
		 * copy given the size only decoded offsets at the default's). */
		void setVoxelSize(double voxel_m)
		{
			voxel_m_ = voxel_m;
			offset_scale_ = float(65534.0 / voxel_m);
		}
		double voxel_m_;
		float offset_scale_;  ///< fixed-point steps per metre of offset
		/** Sorted by key, pass, segment: every voxel, or while spilled
		 * those added since (the same key may be on disk too). */
		std::vector<Voxel> voxels_;
		/** Points added since the last compact(), as one-point voxels. */
		std::vector<Voxel> pending_;
		bool spilled_ = false;
		bool changed_ = true;  ///< since last written to the spill file
		/** The copy on disk: sorted runs, each of passes after the
		 * previous one's (none holds a voxel of another: the set is their
		 * merge, equal keys in run order). A revisited column's new
		 * voxels were merged with the copy and written whole at every
		 * spill: a third of a 58-minute run's tree layer updates. More
		 * runs make every read merge more; past kMaxRuns they are merged
		 * into one. */
		struct Run
		{
			uint64_t offset = 0;
			size_t count = 0;
		};
		static constexpr int kMaxRuns = 4;
		std::array<Run, kMaxRuns> runs_{};
		int n_runs_ = 0;         ///< 0: no copy on disk
		size_t disk_count_ = 0;  ///< voxels in the runs
		uint16_t disk_max_pass_ = 0;
		/** Forgets the copy on disk, giving its space back to `f`. */
		void discardRuns(core::SpillFile& f);
		/** Calls take(voxel) for the voxels of the runs, and after them
		 * on ties those in memory if `with_memory`, in merged order,
		 * reading `chunk` voxels of a run at a time. */
		template <class F>
		void forEachMerged(const core::SpillFile& f, size_t chunk,
		                   bool with_memory, F&& take) const;
		/** Reads every run into `out` (merged: sorted). */
		void readRuns(const core::SpillFile& f, std::vector<Voxel>& out) const;
		/** Merges sorted `b` into sorted `a` (equal voxels: a's first,
		 * not combined). */
		static void mergeSorted(std::vector<Voxel>& a,
		                        const std::vector<Voxel>& b);
		uint64_t keyOf(const Eigen::Vector3f& p) const;
		/** Sorts `add` and merges it into voxels_ (equal keys summed). */
		void mergeIn(std::vector<Voxel>& add);
		/** Sorts voxels_ in place and sums equal (key, pass, segment). */
		void sortAndCombine();
		/** spill() of a set already on disk with voxels added since (of
		 * passes up to `new_max_pass`): the runs and those merged into a
		 * new region of `f` chunk by chunk. */
		void spillMerged(core::SpillFile& f, uint16_t new_max_pass);
		Eigen::Vector3f centreOf(uint64_t key) const;
		Eigen::Vector3f centroid(const Voxel& v) const
		{
			return centreOf(v.key) + offsetOf(v);
		}
	};

	struct Column
	{
		/** Lowest point per ground cell (core::packCellKey(x, y, 0)). */
		core::FlatHashMap<Eigen::Vector3f> lowest;
		SortedVoxels stem;
		std::vector<map::TreeRecord> trees;
		bool dirty = false;
		bool detected = false;  ///< its stems detected at least once
		/** Stem-band voxels (stem.size()) at the last detection. */
		size_t detected_voxels = 0;
		/** Where its trees are shown (published): their correction from
		 * the frame its voxels (and trees) are in to the newest estimate,
		 * until correct() moves them (showColumns). */
		Eigen::Isometry3d shown = Eigen::Isometry3d::Identity();
		uint32_t version = 0;     ///< CorrectionSteps::version
		double pile_density = 0;  ///< takePiledUpColumns' reference
	};
	/** Stem-band voxels per ground cell of a column. */
	static double density(const Column& c);
	/** Detected when the sensor leaves it (update()): changed, and never
	 * detected or grown by layer_redetect_growth since. */
	bool dueInRun(const Column& c) const
	{
		return detect_during_run_ && c.dirty &&
		       (!c.detected || o_.layer_redetect_growth <= 1 ||
		        double(c.stem.size()) >=
		            o_.layer_redetect_growth * double(c.detected_voxels));
	}

	/** addScan's ground cells of one scan, kept between scans (cleared as
	 * used): a square grid of layer_ground_cell_m cells around the sensor
	 * holding the index of each cell's lowest point (-1: none), and for
	 * the cells touched, their column and the height of their lowest point
	 * so far (the column's `lowest` with this scan's). */
	struct ScanCells
	{
		std::vector<int32_t> lowest_of_cell, cell_of_point, touched;
		std::vector<Column*> column_of_cell;
		std::vector<float> low_z;
		/** Lowest of low_z over the cell's neighbourhood (the time
		 * segments' height reference). */
		std::vector<float> tag_z;
		/** low_z's minimum along each row over the neighbourhood's width
		 * (+inf where no cell was touched): tag_z as two 1D minima. */
		std::vector<float> row_min;
	};
	ScanCells scan_cells_;

	TreeOptions o_;
	double column_m_;
	bool detect_during_run_;
	std::unique_ptr<core::SpillFile> spill_;  ///< layer_spill_to_disk
	/** Column's stem voxels in memory (read back if spilled). */
	SortedVoxels& resident(Column& c);
	/** Spills the columns no scan from `sensor` can reach (detected ones
	 * only, when detecting during the run). */
	void spillFar(const Eigen::Vector3d& sensor);
	/** c.stem to the spill file, counted in the stats. */
	void spillColumn(Column& c);
	/** Stem voxels of a column for reading: the column's own if in
	 * memory, else a copy of those in the box [lo, hi) read from disk into
	 * `copy` (not kept). */
	const SortedVoxels& readable(const Column& c, SortedVoxels& copy,
	                             const Eigen::Vector2f& lo,
	                             const Eigen::Vector2f& hi) const;
	/** finish()'s work: every column with new points, two at a time. */
	size_t detectAllDirty(map::CForestMap& map);
	/** Merges every column's buffered points (before detections, which
	 * then only read). */
	void compactAll();
	std::unordered_map<ColumnKey, Column, ColumnKeyHash> cols_;
	uint32_t next_id_ = 1;
	bool released_ = false;  ///< releaseStemVoxels() was called
	uint32_t pass_ = 0;      ///< startPass() count
	double t0_s_ = std::numeric_limits<double>::quiet_NaN();  ///< first scan
	TreeLayerStats stats_;

	Column& column(const ColumnKey& k);
	/** Moves a column's ground cells and trees by T (not its voxels). */
	void moveGroundAndTrees(Column& c, const Eigen::Isometry3d& T);
	void detectColumn(const ColumnKey& k, const map::CForestMap& map);
	/** The stems of column k on its points and its neighbours' margins
	 * (compactAll() first); changes nothing, so finish() runs two at once.
	 * Ids not given yet. */
	std::vector<map::TreeRecord> findTrees(const ColumnKey& k,
	                                       const map::CForestMap& map) const;
	/** Column k's trees are now `found` (ids of trees seen before kept),
	 * found in `ms`. */
	void giveTrees(const ColumnKey& k, std::vector<map::TreeRecord> found,
	               double ms);
	void publish(map::CForestMap& map) const;
};

}  // namespace forest_slam::trees
