#pragma once
// Where a mapping run's observations come from: a finished rawlog, a rawlog
// still being written (--follow), or live sensors (forest-slam online). All
// of them feed the same loop in runMapping(), which writes the outputs, so
// offline and online runs share one pipeline and one set of outputs.
#include <mrpt/obs/CObservation.h>

#include <string>
#include <vector>

namespace forest_slam::pipeline
{
class MappingPipeline;

class ObservationSource
{
   public:
	virtual ~ObservationSource() = default;

	/** The next observation in processing order; nullptr when there are no
	 * more. May block (growing file, live sensors). Throws io::RawlogError
	 * for damaged input. */
	virtual mrpt::obs::CObservation::Ptr next() = 0;

	/** On SIGINT/SIGTERM: false (default) stops the run at once; true keeps
	 * calling next() until it returns nullptr (live sensors: stop grabbing,
	 * then drain what was already captured). Sources that return true must
	 * watch stopSignal() themselves. */
	virtual bool drainOnStop() const { return false; }

	/** True for input that arrives while it is recorded (live sensors, a
	 * growing rawlog): the tree layer then detects stems during the run
	 * ([trees] layer_detect_during_run = auto). */
	virtual bool live() const { return false; }

	/** Called before each observation enters the pipeline (online: light
	 * scans while the pipeline is behind). */
	virtual void willProcess(const mrpt::obs::CObservation& /*obs*/,
	                         MappingPipeline& /*p*/)
	{
	}

	/** Called after each observation went through the pipeline (progress,
	 * status line, latency). */
	virtual void processed(const mrpt::obs::CObservation& /*obs*/,
	                       const MappingPipeline& /*p*/)
	{
	}

	/** Called once after the last observation, before outputs are written. */
	virtual void finish(const MappingPipeline& /*p*/) {}

	/** Writes the source's own files (e.g. the online recording's
	 * statistics) into out_dir; returns the paths written. */
	virtual std::vector<std::string> writeOutputs(
	    const std::string& /*out_dir*/)
	{
		return {};
	}

	/** "rawlog X", "live sensors ..." for log lines. */
	virtual std::string describe() const = 0;
};

/** Installs SIGINT/SIGTERM handlers for its lifetime (runMapping() opens
 * one; open one earlier to cover a source's start-up). Nested scopes share
 * the outermost one's handlers and signal. */
class StopSignalScope
{
   public:
	StopSignalScope();
	~StopSignalScope();
	StopSignalScope(const StopSignalScope&) = delete;
	StopSignalScope& operator=(const StopSignalScope&) = delete;
};

/** The signal (SIGINT/SIGTERM) received inside a StopSignalScope, 0 if none. */
int stopSignal();
/** How many stop signals arrived (a second Ctrl-C: stop draining). */
int stopSignalCount();

}  // namespace forest_slam::pipeline
