#pragma once
// The back-end: keyframes in, loop closures and pose-graph optimisation on
// a worker thread, corrected keyframe poses out.
//
// Determinism: the pipeline hands in keyframes and GNSS fixes in data
// order; the worker processes them in that order. The result of keyframe k
// (the optimised poses, when that keyframe triggered a closure or GNSS
// update) is collected by the pipeline when it makes keyframe
// k + latency_keyframes (resultAt waits if the worker is behind). So the
// worker runs in parallel with the odometry while the trajectory does not
// depend on thread timing.
#include <forest_slam/core/spill_file.h>
#include <forest_slam/loop/loop_detector.h>
#include <forest_slam/loop/loop_options.h>
#include <forest_slam/loop/pose_graph.h>

#include <atomic>
#include <condition_variable>
#include <deque>
#include <exception>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

namespace forest_slam::loop
{
struct GnssFix
{
	double stamp_s = 0;
	size_t keyframe = 0;  ///< latest keyframe made before the fix
	Eigen::Vector3d antenna_in_keyframe = Eigen::Vector3d::Zero();
	Eigen::Vector3d enu = Eigen::Vector3d::Zero();
	Eigen::Vector3d sigma = Eigen::Vector3d::Ones();
};

struct BackEndStats
{
	size_t keyframes = 0, candidates = 0, closures = 0, optimisations = 0;
	/** Of candidates / closures: those from the place descriptor. */
	size_t descriptor_candidates = 0, descriptor_closures = 0;
	size_t gnss_fixes = 0, gnss_outliers = 0;
	double verify_ms = 0, optimise_ms = 0;  ///< worker CPU-side totals
	/** Time the pipeline waited in resultAt for the worker (the back-end
	 * slowing the pipeline down). */
	double wait_ms = 0;
	/** CPU time of the worker thread (threaded back-end; 0 inline): what
	 * the back-end costs the machine, whatever the load. */
	double worker_cpu_ms = 0;
	/** The map frame levelled with gravity at the end (levelling.h): the
	 * final poses include the rotation. */
	bool levelled = false;
	double levelling_deg = 0;      ///< tilt removed
	double levelling_rms_deg = 0;  ///< residual of the keyframes' "up"
	size_t levelling_keyframes = 0;
};

class BackEnd
{
   public:
	/** `threaded` false: everything runs in the caller (tests, debugging);
	 * the results are the same. With `spill`, the clouds of keyframes
	 * older than the newest few are kept there (read back for the loop
	 * candidates they serve): the memory of a long run stays flat. */
	explicit BackEnd(const LoopOptions& o, bool threaded = true,
	                 std::shared_ptr<core::SpillFile> spill = nullptr);
	~BackEnd();
	BackEnd(const BackEnd&) = delete;
	BackEnd& operator=(const BackEnd&) = delete;

	/** Pipeline thread. `kf.odom_edge` must be set (identity for the
	 * first); returns the keyframe id. A failure on the worker (a spill
	 * file that cannot be written, no memory) is thrown by the next call
	 * of addKeyframe, addGnss, resultAt or finish, with "back-end: " before
	 * its message; the worker takes nothing more. */
	size_t addKeyframe(Keyframe kf);
	void addGnss(const GnssFix& f);
	/** Waits until keyframe `id` is processed; true with the optimised
	 * poses of keyframes 0..id if processing it changed the graph. */
	bool resultAt(size_t id, Poses& out);
	/** Processes everything queued, then a final optimisation; afterwards
	 * poses(), closures() and stats() are final. */
	void finish();

	Poses poses() const;
	/** Keyframe reference times (the scans they were made at). */
	std::vector<double> keyframeStamps() const;
	std::vector<Closure> closures() const;
	BackEndStats stats() const;
	std::optional<MapToEnu> mapToEnu() const;
	/** Bytes of the keyframe clouds in memory (any thread). */
	size_t cloudBytes() const { return cloud_bytes_.load(); }
	/** Bytes of keyframe clouds in the spill file. */
	size_t cloudBytesSpilled() const { return cloud_bytes_spilled_.load(); }

   private:
	struct Item
	{
		std::optional<Keyframe> kf;
		std::optional<GnssFix> gnss;
	};
	void run();
	void process(Item& it);
	void processKeyframe(Keyframe& kf);
	bool optimise();
	void level();

	LoopOptions o_;
	bool threaded_;
	// Queue and results (shared, under mutex_).
	mutable std::mutex mutex_;
	std::condition_variable cv_;
	std::deque<Item> queue_;
	std::map<size_t, Poses> results_;
	long processed_ = -1;  ///< last keyframe processed
	bool stop_ = false;
	std::exception_ptr error_;  ///< the worker's failure, for the caller
	/** Throws the worker's failure (mutex_ held). */
	void rethrowLocked() const;
	size_t next_id_ = 0;
	std::atomic<size_t> cloud_bytes_{0}, cloud_bytes_spilled_{0};
	std::thread worker_;
	// Worker state (only the worker touches it until finish()).
	std::vector<Keyframe> kfs_;
	std::vector<PlaceDescriptor> descriptors_;  ///< one per keyframe
	// Keyframe clouds on disk (worker): where each one is, if written.
	std::shared_ptr<core::SpillFile> spill_;
	struct CloudOnDisk
	{
		uint64_t offset = 0;
		size_t count = 0;
		bool written = false;
	};
	std::vector<CloudOnDisk> cloud_disk_;  ///< one per keyframe
	/** Reads the clouds of keyframes first..last back if spilled. */
	void loadClouds(size_t first, size_t last);
	/** Spills the clouds no coming descriptor or ICP source needs. */
	void spillOldClouds(size_t newest);
	PoseGraph graph_;
	std::vector<Closure> closures_;
	BackEndStats stats_;
	double wait_ms_ = 0;  ///< caller's side (resultAt)
	size_t next_attempt_ = 0;
	size_t gnss_since_opt_ = 0;
};

}  // namespace forest_slam::loop
