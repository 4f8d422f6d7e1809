#include <forest_slam/core/log.h>
#include <forest_slam/online/online_job.h>

#include <mrpt/hwdrivers/CVelodyneScanner.h>

namespace forest_slam::online
{
OnlineResult runOnline(const OnlineJob& job)
{
	pipeline::StopSignalScope signals;  // Ctrl-C during start-up counts too
	const auto cfg = OnlineConfig::loadFile(job.config_path);
	using mrpt::hwdrivers::CVelodyneScanner;
	CVelodyneScanner::VELODYNE_DATA_UDP_PORT =
	    static_cast<short>(cfg.velodyne_data_port);
	CVelodyneScanner::VELODYNE_POSITION_UDP_PORT =
	    static_cast<short>(cfg.velodyne_position_port);

	LiveSource source(cfg, job.out_dir);
	source.start();
	pipeline::MappingJob mj;
	mj.config_path = job.config_path;
	mj.out_dir = job.out_dir;
	OnlineResult r;
	r.mapping = pipeline::runMapping(mj, cfg.mapping, source);
	r.live = source.stats();
	r.recording_error = source.recordingError();
	return r;
}

}  // namespace forest_slam::online
