#include <forest_slam/core/log.h>
#include <forest_slam/core/progress.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>

namespace forest_slam::core
{
double ProgressFigures::etaSeconds() const
{
	if (fraction <= 0 || fraction > 1 || wall_seconds <= 0) return -1;
	return wall_seconds * (1.0 - fraction) / fraction;
}

std::string ProgressFigures::format() const
{
	char buf[200];
	std::string eta = "--:--";
	const double e = etaSeconds();
	if (e >= 0)
	{
		const long s = std::lround(e);
		char b2[32];
		std::snprintf(b2, sizeof(b2), "%ld:%02ld", s / 60, s % 60);
		eta = b2;
	}
	std::snprintf(buf, sizeof(buf),
				  "%llu scans  %5.1f%%  %7.1f scans/s  %6.1fx real time  ETA %s",
				  static_cast<unsigned long long>(scans),
				  fraction >= 0 ? 100.0 * fraction : 0.0, scansPerSecond(),
				  realTimeFactor(), eta.c_str());
	return buf;
}

ProgressReporter::ProgressReporter(int interactive, double log_period_s)
	: interactive_(interactive < 0 ? ::isatty(2) != 0 : interactive != 0),
	  period_s_(interactive_ ? 0.2 : log_period_s),
	  start_(std::chrono::steady_clock::now()),
	  last_print_(start_)
{
}

void ProgressReporter::update(uint64_t scans, double fraction, double data_s)
{
	const auto now = std::chrono::steady_clock::now();
	fig_.scans = scans;
	fig_.fraction = fraction;
	fig_.data_seconds = data_s;
	fig_.wall_seconds = std::chrono::duration<double>(now - start_).count();
	if (std::chrono::duration<double>(now - last_print_).count() < period_s_)
		return;
	last_print_ = now;
	print(false);
}

void ProgressReporter::finish()
{
	fig_.wall_seconds = std::chrono::duration<double>(
							std::chrono::steady_clock::now() - start_)
							.count();
	print(true);
}

void ProgressReporter::print(bool final_line)
{
	if (logLevel() == LogLevel::Quiet) return;
	if (interactive_)
	{
		const int width = 30;
		const double f = fig_.fraction < 0 ? 0 : std::min(1.0, fig_.fraction);
		const int filled = static_cast<int>(f * width);
		std::string bar(filled, '#');
		bar += std::string(width - filled, '.');
		std::fprintf(stderr, "\r[%s] %s%s", bar.c_str(), fig_.format().c_str(),
					 final_line ? "\n" : "");
		std::fflush(stderr);
	}
	else
		logMessage(LogLevel::Info,
				   std::string(final_line ? "done: " : "progress: ") +
					   fig_.format());
}

}  // namespace forest_slam::core
