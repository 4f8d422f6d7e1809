#include <forest_slam/core/atomic_file.h>
#include <forest_slam/core/log.h>
#include <forest_slam/core/memory.h>
#include <forest_slam/core/progress.h>
#include <forest_slam/io/rawlog_follower.h>
#include <forest_slam/io/rawlog_reader.h>
#include <forest_slam/io/tum.h>
#include <forest_slam/outputs/write_outputs.h>
#include <forest_slam/pipeline/mapping_job.h>

#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/serialization/CArchive.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <sstream>

namespace forest_slam::pipeline
{
namespace
{
std::atomic<int> g_stop_signal{0};
std::atomic<int> g_stop_signals{0};  // how many arrived
int g_signal_scopes = 0;             // nesting depth of StopSignalScope
struct sigaction g_old_int
{
}, g_old_term{};
extern "C" void onStopSignal(int sig)
{
	g_stop_signal = sig;
	g_stop_signals++;
}
}  // namespace

StopSignalScope::StopSignalScope()
{
	if (g_signal_scopes++ > 0) return;
	g_stop_signal = 0;
	g_stop_signals = 0;
	struct sigaction sa
	{
	};
	sa.sa_handler = onStopSignal;
	sigemptyset(&sa.sa_mask);
	sigaction(SIGINT, &sa, &g_old_int);
	sigaction(SIGTERM, &sa, &g_old_term);
}

StopSignalScope::~StopSignalScope()
{
	if (--g_signal_scopes > 0) return;
	sigaction(SIGINT, &g_old_int, nullptr);
	sigaction(SIGTERM, &g_old_term, nullptr);
}

int stopSignal()
{
	return g_stop_signal.load();
}
int stopSignalCount()
{
	return g_stop_signals.load();
}

namespace
{
std::string jsonEscape(const std::string& s)
{
	std::string o;
	for (char c : s)
	{
		if (c == '"' || c == '\\') o += '\\';
		if (static_cast<unsigned char>(c) < 0x20)
		{
			char b[8];
			std::snprintf(b, sizeof(b), "\\u%04x", c);
			o += b;
			continue;
		}
		o += c;
	}
	return o;
}
/** {"median": .., "p95": .., "max": ..} of `v` (sorted in place). */
std::string distributionJson(std::vector<double>& v)
{
	std::sort(v.begin(), v.end());
	const auto at = [&](double q)
	{
		return v.empty() ? 0.0
		                 : v[std::min(v.size() - 1,
		                              static_cast<size_t>(q * v.size()))];
	};
	std::ostringstream os;
	os << "{\"median\": " << at(0.5) << ", \"p95\": " << at(0.95)
	   << ", \"max\": " << (v.empty() ? 0.0 : v.back()) << "}";
	return os.str();
}

/** {"ground": {"median":..,"p95":..,"max":..}, ...} over the scans, with the
 * tree layer ("trees": per scan) and the back-end hook ("backend", with a
 * back-end only) last. */
std::string stageTimesJson(const std::vector<odometry::ScanTiming>& t,
                           std::vector<double> tree_ms,
                           std::vector<double> backend_ms)
{
	using T = odometry::ScanTiming;
	const std::pair<const char*, double T::*> stages[] = {
	    {"deskew", &T::deskew_ms},     {"ground", &T::ground_ms},
	    {"cluster", &T::cluster_ms},   {"features", &T::features_ms},
	    {"register", &T::register_ms}, {"insert", &T::insert_ms}};
	std::ostringstream os;
	os << "{";
	bool first = true;
	for (const auto& [name, field] : stages)
	{
		std::vector<double> v;
		for (const auto& x : t) v.push_back(x.*field);
		os << (first ? "" : ", ") << "\"" << name
		   << "\": " << distributionJson(v);
		first = false;
	}
	os << ", \"trees\": " << distributionJson(tree_ms);
	if (!backend_ms.empty())
		os << ", \"backend\": " << distributionJson(backend_ms);
	os << "}";
	return os.str();
}

/** Back-end figures for run_summary.json ("null" without a back-end). */
std::string loopJson(const loop::BackEnd* b,
                     const std::optional<outputs::GeoOptions>& geo)
{
	if (!b) return "null";
	const auto st = b->stats();
	std::ostringstream os;
	os << "{\"keyframes\": " << st.keyframes
	   << ", \"candidates\": " << st.candidates
	   << ", \"closures\": " << st.closures
	   << ", \"descriptor_candidates\": " << st.descriptor_candidates
	   << ", \"descriptor_closures\": " << st.descriptor_closures
	   << ", \"optimisations\": " << st.optimisations
	   << ", \"gnss_fixes\": " << st.gnss_fixes
	   << ", \"gnss_outliers\": " << st.gnss_outliers
	   << ", \"verify_ms\": " << st.verify_ms
	   << ", \"optimise_ms\": " << st.optimise_ms
	   << ", \"wait_ms\": " << st.wait_ms
	   << ", \"worker_cpu_ms\": " << st.worker_cpu_ms
	   << ", \"levelled\": " << (st.levelled ? "true" : "false")
	   << ", \"levelling_deg\": " << st.levelling_deg
	   << ", \"levelling_rms_deg\": " << st.levelling_rms_deg
	   << ", \"levelling_keyframes\": " << st.levelling_keyframes;
	if (const auto e = b->mapToEnu())
	{
		os << ", \"map_to_enu\": {\"yaw_deg\": " << e->yaw * 180 / M_PI
		   << ", \"x_m\": " << e->t.x() << ", \"y_m\": " << e->t.y()
		   << ", \"z_m\": " << e->t.z();
		if (geo)  // the ENU origin: the first fix
		{
			const auto prec = os.precision(10);
			os << ", \"origin_lat_deg\": " << geo->origin_lat_deg
			   << ", \"origin_lon_deg\": " << geo->origin_lon_deg;
			os.precision(prec);
			os << ", \"origin_alt_m\": " << geo->origin_alt_m;
		}
		os << "}";
	}
	os << "}";
	return os.str();
}

/** Every verified loop candidate: keyframe times, verdict, gates, and the
 * measured relative pose (from^-1 to). */
void writeLoopClosures(const loop::BackEnd& b, const std::string& path)
{
	const auto t = b.keyframeStamps();
	core::writeFileAtomically(
	    path,
	    [&](std::ostream& os)
	    {
		    os << "from_t_s,to_t_s,accepted,reason,overlap,rmse_m,chi2,"
		          "travelled_m,x,y,z,qx,qy,qz,qw,candidate,descriptor_"
		          "distance,error_m,error_deg\n";
		    os << std::fixed;
		    os.precision(6);
		    for (const auto& c : b.closures())
		    {
			    const Eigen::Quaterniond q(c.T.linear());
			    os << t.at(c.from) << ',' << t.at(c.to) << ','
			       << (c.accepted ? 1 : 0) << ',' << c.reason << ','
			       << c.overlap << ',' << c.rmse_m << ',' << c.chi2 << ','
			       << c.travelled_m << ',' << c.T.translation().x() << ','
			       << c.T.translation().y() << ',' << c.T.translation().z()
			       << ',' << q.x() << ',' << q.y() << ',' << q.z() << ','
			       << q.w() << ','
			       << (c.descriptor ? "descriptor" : "geometric") << ','
			       << (c.descriptor ? c.descriptor_distance : 0.0) << ','
			       << c.error_m << ',' << c.error_deg << '\n';
		    }
	    });
}
}  // namespace

namespace
{
/** A finished rawlog (gzip or plain), with a progress bar. */
class RawlogSource : public ObservationSource
{
   public:
	explicit RawlogSource(const MappingJob& job)
	    : reader_(job.rawlog_path), progress_(job.progress_tty)
	{
	}
	mrpt::obs::CObservation::Ptr next() override { return reader_.next(); }
	void processed(const mrpt::obs::CObservation&,
	               const MappingPipeline& p) override
	{
		if (p.stats().scans_in == scans_seen_) return;
		scans_seen_ = p.stats().scans_in;
		progress_.update(p.stats().scans_mapped, reader_.fractionRead(),
		                 p.stats().dataSeconds());
	}
	void finish(const MappingPipeline& p) override
	{
		progress_.update(p.stats().scans_mapped, reader_.fractionRead(),
		                 p.stats().dataSeconds());
		progress_.finish();
	}
	std::string describe() const override { return reader_.path(); }

   private:
	io::RawlogReader reader_;
	core::ProgressReporter progress_;
	uint64_t scans_seen_ = 0;
};

/** A rawlog another process is still writing (--follow). */
class FollowedRawlogSource : public ObservationSource
{
   public:
	explicit FollowedRawlogSource(const MappingJob& job)
	    : follower_(job.rawlog_path, followOptions(job)),
	      progress_(job.progress_tty)
	{
		if (follower_.gzip())
			FS_LOG_WARN(job.rawlog_path
			            << " is gzip-compressed: followed as its compressed "
			               "blocks are flushed (a plain rawlog is read record "
			               "by record)");
	}
	mrpt::obs::CObservation::Ptr next() override { return follower_.next(); }
	bool live() const override { return true; }
	void processed(const mrpt::obs::CObservation&,
	               const MappingPipeline& p) override
	{
		if (p.stats().scans_in == scans_seen_) return;
		scans_seen_ = p.stats().scans_in;
		progress_.update(p.stats().scans_mapped, -1, p.stats().dataSeconds());
	}
	void finish(const MappingPipeline& p) override
	{
		progress_.update(p.stats().scans_mapped, -1, p.stats().dataSeconds());
		progress_.finish();
	}
	std::string describe() const override
	{
		return follower_.path() + " (following as it grows)";
	}

   private:
	static io::FollowOptions followOptions(const MappingJob& job)
	{
		io::FollowOptions o;
		o.idle_timeout_s = job.follow_timeout_s;
		o.should_stop = [] { return stopSignal() != 0; };
		return o;
	}
	io::RawlogFollower follower_;
	core::ProgressReporter progress_;
	uint64_t scans_seen_ = 0;
};
}  // namespace

MappingResult runMapping(const MappingJob& job)
{
	const MappingConfig cfg = MappingConfig::loadFile(job.config_path);
	StopSignalScope signals;  // also while --follow waits for the file
	std::unique_ptr<ObservationSource> source;
	if (job.follow)
		source = std::make_unique<FollowedRawlogSource>(job);
	else
		source = std::make_unique<RawlogSource>(job);
	return runMapping(job, cfg, *source);
}

MappingResult runMapping(const MappingJob& job, const MappingConfig& cfg,
                         ObservationSource& source)
{
	std::optional<core::Trajectory> poses;
	if (!job.poses_path.empty())
	{
		poses = io::readTum(job.poses_path);
		if (cfg.pipeline.poseSource() != PoseSource::Trajectory)
			throw core::ConfigError(
			    "--poses given but " + job.config_path +
			    " has [pipeline] pose_source=" + cfg.pipeline.pose_source +
			    " (set pose_source=trajectory)");
	}
	core::ensureDirectory(job.out_dir);
	// A previous run killed while writing its outputs left temp files.
	for (const auto& f : core::removeStaleTempFiles(job.out_dir))
		FS_LOG_WARN("removed " << f
		                       << ", left by a run killed while writing it");
	// "auto" settles here, where the input is known: a recorded rawlog
	// has its trees detected once, at the end.
	MappingConfig run_cfg = cfg;
	run_cfg.trees.layer_detect_during_run =
	    cfg.trees.detectDuringRun(source.live()) ? "true" : "false";
	if (run_cfg.trees.layer_enabled)
		FS_LOG_INFO("tree layer: stems detected "
		            << (run_cfg.trees.layer_detect_during_run == "true"
		                    ? "during the run"
		                    : "once, at the end of the run"));
	// The workers nobody waits for: at the lowest priority for a recorded
	// rawlog, a step below for live input (core/memory.h).
	core::setBackgroundNice(source.live() ? core::kBackgroundNiceLive
	                                      : core::kBackgroundNiceRecorded);
	MappingPipeline pipeline(run_cfg, poses);

	MappingResult result;
	StopSignalScope signals;
	const auto t0 = std::chrono::steady_clock::now();
	const double mem_period_s = cfg.pipeline.memory_report_period_s;
	double next_mem_s = mem_period_s;
	// Freed heap goes back to the system every 30 s of data: the threads
	// free and allocate tables, columns and clouds all the time, and glibc
	// keeps what was freed (robot run: RSS -150 MB at 900 s of data, for
	// 10-30 ms per call; doc/performance.md).
	constexpr double kTrimPeriodS = 30;
	double next_trim_s = kTrimPeriodS;
	FS_LOG_INFO("mapping " << source.describe() << " with " << job.config_path
	                       << " -> " << job.out_dir);
	while (!pipeline.reachedScanLimit())
	{
		if (g_stop_signal && !result.interrupted)
		{
			result.interrupted = true;
			FS_LOG_WARN("signal "
			            << g_stop_signal.load()
			            << (source.drainOnStop()
			                    ? " received: stopping, draining the "
			                      "queue, writing outputs"
			                    : " received: stopping, writing outputs"));
			if (!source.drainOnStop()) break;
		}
		mrpt::obs::CObservation::Ptr obs;
		try
		{
			obs = source.next();
		}
		catch (const io::RawlogError& e)
		{
			result.input_damaged = true;
			result.damage_message = e.what();
			FS_LOG_ERROR(e.what() << " -- stopping here; outputs cover the "
			                      << pipeline.stats().scans_mapped
			                      << " scans mapped before the damage");
			break;
		}
		if (!obs) break;
		source.willProcess(*obs, pipeline);
		pipeline.process(obs);
		source.processed(*obs, pipeline);
		if (pipeline.stats().dataSeconds() >= next_trim_s)
		{
			const double mb = core::releaseFreedHeap();
			FS_LOG_DEBUG("freed heap given back at "
			             << next_trim_s << " s of data: " << mb << " MB");
			// Once after a gap in the data, not once per period missed.
			next_trim_s = pipeline.stats().dataSeconds() + kTrimPeriodS;
		}
		if (mem_period_s > 0 && pipeline.stats().dataSeconds() >= next_mem_s)
		{
			result.memory_curve.push_back(sampleMemory(pipeline));
			FS_LOG_INFO("memory at "
			            << next_mem_s << " s of data: "
			            << describeMemory(result.memory_curve.back()));
			next_mem_s += mem_period_s;
		}
	}
	if (g_stop_signal && !result.interrupted)  // arrived while next() waited
	{
		result.interrupted = true;
		FS_LOG_WARN("signal " << g_stop_signal.load()
		                      << " received: stopped, writing outputs");
	}
	result.scan_thread_cpu_s = core::threadCpuByName();
	pipeline.finish();
	source.finish(pipeline);
	result.stats = pipeline.stats();
	result.wall_seconds =
	    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
	        .count();
	result.memory_end = sampleMemory(pipeline);
	FS_LOG_INFO(
	    "memory at the end of mapping: " << describeMemory(result.memory_end));
	result.outputs = writeOutputs(pipeline, result, job.out_dir);
	for (const auto& f : source.writeOutputs(job.out_dir))
		result.outputs.push_back(f);
	return result;
}

namespace
{
/** {"forest-slam": 61.2, "fs-localmap": 9.8, ...}: each thread's CPU. */
std::string threadCpuJson(
    const std::vector<std::pair<std::string, double>>& threads)
{
	std::ostringstream os;
	os << "{";
	for (size_t i = 0; i < threads.size(); i++)
		os << (i ? ", " : "") << "\"" << jsonEscape(threads[i].first)
		   << "\": " << threads[i].second;
	os << "}";
	return os.str();
}
}  // namespace

std::vector<std::string> writeOutputs(const MappingPipeline& p,
                                      const MappingResult& r,
                                      const std::string& dir)
{
	const auto t_out = std::chrono::steady_clock::now();
	std::vector<std::string> written;
	const auto& s = r.stats;
	const auto& cfg = p.config();
	outputs::RunFigures fig;
	fig.scans = s.scans_mapped;
	fig.data_seconds = s.dataSeconds();
	fig.wall_seconds = r.wall_seconds;
	if (p.backEnd())
		fig.loop_closures = static_cast<int>(p.backEnd()->stats().closures);
	// Georeferenced outputs: [georeference] when given, else the map->ENU
	// transform the back-end estimated from GNSS (ENU at the first fix).
	outputs::GeoOptions geo = cfg.georeference;
	if (!geo.enabled())
		if (const auto g = p.estimatedGeoreference())
		{
			geo = *g;
			FS_LOG_INFO(
			    "outputs georeferenced with the back-end's GNSS "
			    "estimate: ENU at the first fix ("
			    << geo.origin_lat_deg << ", " << geo.origin_lon_deg << ", "
			    << geo.origin_alt_m << " m) -> UTM");
		}
	// trajectory, forest.map, trees.csv (the tree layer) and the rest.
	const auto out = outputs::writeRunOutputs(
	    {p.trajectory(), p.forestMap(), p.outputCollector(), cfg.outputs, geo,
	     cfg.trees, fig},
	    dir);
	for (const auto& f : out.files) written.push_back(f.path);
	const auto& col = p.outputCollector();
	// To the run summary: mapping, the tree layer's finish and the outputs.
	const double total_wall =
	    r.wall_seconds +
	    std::chrono::duration<double>(std::chrono::steady_clock::now() - t_out)
	        .count();
	const double cpu_s = core::processCpuSeconds();

	// The tree layer's share: its store and detections per scan, its
	// corrections (in-run merges of the passes, the final correction: on
	// the back-end's side) and its end-of-run detections.
	const auto* layer = p.treeLayer();
	double tree_total_ms = s.tree_finish_ms;
	for (double v : s.tree_ms) tree_total_ms += v;
	if (layer) tree_total_ms += layer->stats().correct_ms;
	// Its CPU time on every thread it uses (the end-of-run detections and
	// the corrections run on two): its cost in the process CPU.
	const double tree_cpu_ms = layer ? layer->stats().cpu_ms : 0;
	// Of it, the updates (store, spill, corrections, detections during the
	// run) apart from the detection of every column at the end (finish).
	const double tree_update_cpu_ms =
	    layer ? tree_cpu_ms - layer->stats().finish_cpu_ms : 0;
	const std::string summary = dir + "/run_summary.json";
	core::writeFileAtomically(
	    summary,
	    [&](std::ostream& os)
	    {
		    const double rt =
		        r.wall_seconds > 0 ? s.dataSeconds() / r.wall_seconds : 0;
		    os << "{\n"
		       << "  \"observations\": " << s.observations << ",\n"
		       << "  \"scans_in\": " << s.scans_in << ",\n"
		       << "  \"scans_mapped\": " << s.scans_mapped << ",\n"
		       << "  \"scans_empty\": " << s.scans_empty << ",\n"
		       << "  \"scans_out_of_order\": " << s.scans_out_of_order << ",\n"
		       << "  \"scans_outside_poses\": " << s.scans_outside_poses
		       << ",\n"
		       << "  \"scans_unreadable\": " << s.scans_unreadable << ",\n"
		       << "  \"scans_degenerate\": " << s.scans_degenerate << ",\n"
		       << "  \"scans_unregistered\": " << s.scans_unregistered << ",\n"
		       << "  \"scans_light\": " << s.scans_light << ",\n"
		       << "  \"scans_imu\": " << s.scans_imu << ",\n"
		       << "  \"imu_rejected\": " << s.imu_rejected << ",\n"
		       << "  \"scans_duplicate\": " << s.scans_duplicate << ",\n"
		       << "  \"points_nonfinite\": " << s.points_nonfinite << ",\n"
		       << "  \"lidar_gaps\": " << s.lidar_gaps << ",\n"
		       << "  \"imu_gaps\": " << s.imu_gaps << ",\n"
		       << "  \"gnss_rejected\": " << s.gnss_rejected << ",\n"
		       << "  \"imu\": " << s.imu << ",\n"
		       << "  \"gnss\": " << s.gnss << ",\n"
		       << "  \"other\": " << s.other << ",\n"
		       << "  \"points_in\": " << s.points_in << ",\n"
		       << "  \"data_seconds\": " << s.dataSeconds() << ",\n"
		       << "  \"wall_seconds\": " << r.wall_seconds << ",\n"
		       << "  \"scans_per_second\": "
		       << (r.wall_seconds > 0 ? s.scans_mapped / r.wall_seconds : 0)
		       << ",\n"
		       << "  \"real_time_factor\": " << rt << ",\n"
		       << "  \"total_wall_seconds\": " << total_wall << ",\n"
		       << "  \"scans_per_second_end_to_end\": "
		       << (total_wall > 0 ? s.scans_mapped / total_wall : 0) << ",\n"
		       << "  \"cpu_seconds\": " << cpu_s << ",\n"
		       << "  \"scan_thread_cpu_seconds\": "
		       << threadCpuJson(r.scan_thread_cpu_s) << ",\n"
		       << "  \"heap_huge_pages\": "
		       << (core::heapOnHugePages() ? "true" : "false") << ",\n"
		       << "  \"stage_ms\": "
		       << stageTimesJson(s.stage_ms, s.tree_ms, s.backend_ms) << ",\n"
		       << "  \"map_edge_voxels\": " << p.forestMap().edgePointCount()
		       << ",\n"
		       << "  \"map_planar_voxels\": "
		       << p.forestMap().planarPointCount() << ",\n"
		       << "  \"map_submaps\": " << p.forestMap().submaps().size()
		       << ",\n"
		       << "  \"trees\": " << out.trees << ",\n"
		       << "  \"tree_layer\": {\"total_ms\": " << tree_total_ms
		       << ", \"share_of_wall\": "
		       << (r.wall_seconds > 0 ? tree_total_ms / (1000 * r.wall_seconds)
		                              : 0)
		       << ", \"cpu_ms\": " << tree_cpu_ms << ", \"share_of_cpu\": "
		       << (cpu_s > 0 ? tree_cpu_ms / (1000 * cpu_s) : 0)
		       << ", \"update_cpu_ms\": " << tree_update_cpu_ms
		       << ", \"update_share_of_cpu\": "
		       << (cpu_s > 0 ? tree_update_cpu_ms / (1000 * cpu_s) : 0)
		       << ", \"store_cpu_ms\": "
		       << (layer ? layer->stats().store_cpu_ms : 0)
		       << ", \"correct_cpu_ms\": "
		       << (layer ? layer->stats().correct_cpu_ms : 0)
		       << ", \"spill_cpu_ms\": "
		       << (layer ? layer->stats().spill_cpu_ms : 0)
		       << ", \"spill_runs_appended\": "
		       << (layer ? layer->stats().spill_runs_appended : 0)
		       << ", \"spill_runs_merged\": "
		       << (layer ? layer->stats().spill_runs_merged : 0)
		       << ", \"finish_ms\": " << s.tree_finish_ms
		       << ", \"correct_ms\": "
		       << (layer ? layer->stats().correct_ms : 0)
		       << ", \"detections\": "
		       << (layer ? layer->stats().detections : 0)
		       << ", \"detections_in_run\": "
		       << (layer ? layer->stats().detections_in_run : 0)
		       << ", \"redetections_in_run\": "
		       << (layer ? layer->stats().redetections_in_run : 0)
		       << ", \"detect_ms\": " << (layer ? layer->stats().detect_ms : 0)
		       << ", \"stem_voxels\": "
		       << (layer ? layer->stats().stored_voxels +
		                       layer->stats().released_voxels
		                 : 0)
		       << "},\n"
		       << "  \"output_collect_ms_per_scan\": "
		       << (col.scans() ? 1e3 * col.collectSeconds() / col.scans() : 0.0)
		       << ",\n"
		       << "  \"output_write_seconds\": " << out.seconds << ",\n"
		       << "  \"loop\": "
		       << loopJson(p.backEnd(), p.estimatedGeoreference()) << ",\n"
		       << "  \"keyframes\": " << out.keyframes << ",\n"
		       << "  \"dense_points\": " << out.dense_points << ",\n"
		       << "  \"peak_memory_mb\": " << outputs::peakMemoryMb() << ",\n"
		       << "  \"memory\": "
		       << memoryJson(r.memory_end, outputs::peakMemoryMb(),
		                     r.memory_curve)
		       << ",\n"
		       << "  \"input_damaged\": "
		       << (r.input_damaged ? "true" : "false") << ",\n"
		       << "  \"damage\": \"" << jsonEscape(r.damage_message) << "\",\n"
		       << "  \"interrupted\": " << (r.interrupted ? "true" : "false")
		       << "\n"
		       << "}\n";
	    });
	written.push_back(summary);
	if (p.backEnd())
	{
		const std::string f = dir + "/loop_closures.csv";
		writeLoopClosures(*p.backEnd(), f);
		written.push_back(f);
	}
	return written;
}

std::shared_ptr<map::CForestMap> loadForestMap(const std::string& path)
{
	map::registerForestMapClasses();
	mrpt::io::CFileGZInputStream in;
	if (!in.open(path))
		throw std::runtime_error("cannot open forest map '" + path + "'");
	auto arch = mrpt::serialization::archiveFrom(in);
	mrpt::serialization::CSerializable::Ptr obj;
	try
	{
		obj = arch.ReadObject();
	}
	catch (const std::exception& e)
	{
		throw std::runtime_error("'" + path +
		                         "' is not a readable forest map: " + e.what());
	}
	auto m = std::dynamic_pointer_cast<map::CForestMap>(obj);
	if (!m)
		throw std::runtime_error("'" + path + "' holds a " +
		                         obj->GetRuntimeClass()->className +
		                         ", not a forest_slam::map::CForestMap");
	return m;
}

}  // namespace forest_slam::pipeline
