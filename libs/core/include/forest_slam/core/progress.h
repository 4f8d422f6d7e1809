#pragma once
// Progress of a long run: a redrawn bar on a terminal, a log line every few
// seconds otherwise (CI logs, nohup). Figures: scans done, % of the input,
// scans/s, real-time factor (data seconds per wall second), ETA.
#include <chrono>
#include <cstdint>
#include <string>

namespace forest_slam::core
{
struct ProgressFigures
{
	uint64_t scans = 0;
	double fraction = 0;  ///< of the input consumed, [0,1]; <0 unknown
	double data_seconds = 0;  ///< sensor time covered so far
	double wall_seconds = 0;
	double scansPerSecond() const
	{
		return wall_seconds > 0 ? scans / wall_seconds : 0;
	}
	double realTimeFactor() const
	{
		return wall_seconds > 0 ? data_seconds / wall_seconds : 0;
	}
	/** Seconds left, or <0 if unknown. */
	double etaSeconds() const;
	/** "123 scans  45.0%  210.3 scans/s  21.0x real time  ETA 0:12" */
	std::string format() const;
};

class ProgressReporter
{
   public:
	/** `interactive` = draw a bar (default: stderr is a tty). */
	explicit ProgressReporter(int interactive = -1, double log_period_s = 5.0);
	/** Call per processed scan; cheap when nothing is printed. */
	void update(uint64_t scans, double fraction, double data_seconds);
	/** Final line (always printed). */
	void finish();
	const ProgressFigures& figures() const { return fig_; }

   private:
	bool interactive_;
	double period_s_;
	std::chrono::steady_clock::time_point start_, last_print_;
	ProgressFigures fig_;
	void print(bool final_line);
};

}  // namespace forest_slam::core
