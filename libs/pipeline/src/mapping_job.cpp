#include <forest_slam/core/atomic_file.h>
#include <forest_slam/core/log.h>
#include <forest_slam/core/progress.h>
#include <forest_slam/io/rawlog_reader.h>
#include <forest_slam/io/tum.h>
#include <forest_slam/pipeline/mapping_job.h>

#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
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
extern "C" void onStopSignal(int sig) { g_stop_signal = sig; }

/** Installs SIGINT/SIGTERM handlers for the job's lifetime. */
struct StopSignalGuard
{
	struct sigaction old_int{}, old_term{};
	StopSignalGuard()
	{
		g_stop_signal = 0;
		struct sigaction sa{};
		sa.sa_handler = onStopSignal;
		sigemptyset(&sa.sa_mask);
		sigaction(SIGINT, &sa, &old_int);
		sigaction(SIGTERM, &sa, &old_term);
	}
	~StopSignalGuard()
	{
		sigaction(SIGINT, &old_int, nullptr);
		sigaction(SIGTERM, &old_term, nullptr);
	}
};

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
/** {"ground": {"median":..,"p95":..,"max":..}, ...} over the scans. */
std::string stageTimesJson(const std::vector<odometry::ScanTiming>& t)
{
	using T = odometry::ScanTiming;
	const std::pair<const char*, double T::*> stages[] = {
		{"deskew", &T::deskew_ms},	 {"ground", &T::ground_ms},
		{"cluster", &T::cluster_ms}, {"features", &T::features_ms},
		{"register", &T::register_ms}, {"insert", &T::insert_ms}};
	std::ostringstream os;
	os << "{";
	bool first = true;
	for (const auto& [name, field] : stages)
	{
		std::vector<double> v;
		for (const auto& x : t) v.push_back(x.*field);
		std::sort(v.begin(), v.end());
		const auto at = [&](double q) {
			return v.empty() ? 0.0 : v[std::min(v.size() - 1, static_cast<size_t>(q * v.size()))];
		};
		os << (first ? "" : ", ") << "\"" << name << "\": {\"median\": " << at(0.5)
		   << ", \"p95\": " << at(0.95) << ", \"max\": " << (v.empty() ? 0.0 : v.back())
		   << "}";
		first = false;
	}
	os << "}";
	return os.str();
}
}  // namespace

MappingResult runMapping(const MappingJob& job)
{
	const MappingConfig cfg = MappingConfig::loadFile(job.config_path);
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
	io::RawlogReader reader(job.rawlog_path);
	MappingPipeline pipeline(cfg, poses);

	MappingResult result;
	StopSignalGuard signals;
	core::ProgressReporter progress(job.progress_tty);
	const auto t0 = std::chrono::steady_clock::now();
	FS_LOG_INFO("mapping " << job.rawlog_path << " with " << job.config_path
						   << " -> " << job.out_dir);
	while (!pipeline.reachedScanLimit())
	{
		if (g_stop_signal)
		{
			result.interrupted = true;
			FS_LOG_WARN("signal " << g_stop_signal.load()
								  << " received: stopping, writing outputs");
			break;
		}
		mrpt::obs::CObservation::Ptr obs;
		try
		{
			obs = reader.next();
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
		const auto scans_before = pipeline.stats().scans_in;
		pipeline.process(obs);
		if (pipeline.stats().scans_in != scans_before)
			progress.update(pipeline.stats().scans_mapped, reader.fractionRead(),
							pipeline.stats().dataSeconds());
	}
	progress.update(pipeline.stats().scans_mapped, reader.fractionRead(),
					pipeline.stats().dataSeconds());
	progress.finish();
	result.stats = pipeline.stats();
	result.wall_seconds = std::chrono::duration<double>(
							  std::chrono::steady_clock::now() - t0)
							  .count();
	result.outputs = writeOutputs(pipeline, result, job.out_dir);
	return result;
}

std::vector<std::string> writeOutputs(
	const MappingPipeline& p, const MappingResult& r, const std::string& dir)
{
	std::vector<std::string> written;
	const std::string traj = dir + "/trajectory.tum";
	io::writeTum(traj, p.trajectory());
	written.push_back(traj);

	const std::string map_path = dir + "/forest.map";
	{
		mrpt::io::CFileGZOutputStream out;
		if (!out.open(core::tempPathFor(map_path), 1))
			throw std::runtime_error("cannot create '" + map_path + "'");
		auto arch = mrpt::serialization::archiveFrom(out);
		arch << p.forestMap();
		out.close();
		core::commitTempFile(map_path);
	}
	written.push_back(map_path);

	const auto& s = r.stats;
	const std::string summary = dir + "/run_summary.json";
	core::writeFileAtomically(summary, [&](std::ostream& os) {
		const double rt = r.wall_seconds > 0 ? s.dataSeconds() / r.wall_seconds : 0;
		os << "{\n"
		   << "  \"observations\": " << s.observations << ",\n"
		   << "  \"scans_in\": " << s.scans_in << ",\n"
		   << "  \"scans_mapped\": " << s.scans_mapped << ",\n"
		   << "  \"scans_empty\": " << s.scans_empty << ",\n"
		   << "  \"scans_out_of_order\": " << s.scans_out_of_order << ",\n"
		   << "  \"scans_outside_poses\": " << s.scans_outside_poses << ",\n"
		   << "  \"scans_unreadable\": " << s.scans_unreadable << ",\n"
		   << "  \"scans_degenerate\": " << s.scans_degenerate << ",\n"
		   << "  \"scans_unregistered\": " << s.scans_unregistered << ",\n"
		   << "  \"imu\": " << s.imu << ",\n"
		   << "  \"gnss\": " << s.gnss << ",\n"
		   << "  \"other\": " << s.other << ",\n"
		   << "  \"points_in\": " << s.points_in << ",\n"
		   << "  \"data_seconds\": " << s.dataSeconds() << ",\n"
		   << "  \"wall_seconds\": " << r.wall_seconds << ",\n"
		   << "  \"scans_per_second\": "
		   << (r.wall_seconds > 0 ? s.scans_mapped / r.wall_seconds : 0) << ",\n"
		   << "  \"real_time_factor\": " << rt << ",\n"
		   << "  \"stage_ms\": " << stageTimesJson(s.stage_ms) << ",\n"
		   << "  \"map_edge_voxels\": " << p.forestMap().edgePointCount() << ",\n"
		   << "  \"map_planar_voxels\": " << p.forestMap().planarPointCount() << ",\n"
		   << "  \"map_submaps\": " << p.forestMap().submaps().size() << ",\n"
		   << "  \"input_damaged\": " << (r.input_damaged ? "true" : "false") << ",\n"
		   << "  \"damage\": \"" << jsonEscape(r.damage_message) << "\",\n"
		   << "  \"interrupted\": " << (r.interrupted ? "true" : "false") << "\n"
		   << "}\n";
	});
	written.push_back(summary);
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
		throw std::runtime_error(
			"'" + path + "' is not a readable forest map: " + e.what());
	}
	auto m = std::dynamic_pointer_cast<map::CForestMap>(obj);
	if (!m)
		throw std::runtime_error(
			"'" + path + "' holds a " + obj->GetRuntimeClass()->className +
			", not a forest_slam::map::CForestMap");
	return m;
}

}  // namespace forest_slam::pipeline
