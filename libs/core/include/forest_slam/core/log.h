#pragma once
// Minimal leveled logging to stderr. Kept tiny on purpose: the apps print a
// progress bar on stdout/stderr and the log must not interleave mid-line.
#include <sstream>
#include <string>

namespace forest_slam::core
{
enum class LogLevel
{
	Debug = 0,
	Info = 1,
	Warn = 2,
	Error = 3,
	Quiet = 4
};

void setLogLevel(LogLevel level);
LogLevel logLevel();
/** Parses "debug|info|warn|error|quiet"; throws std::invalid_argument. */
LogLevel parseLogLevel(const std::string& name);

void logMessage(LogLevel level, const std::string& msg);

/** Logs `msg` only the first time `key` is seen (faults named once). */
void logOnce(LogLevel level, const std::string& key, const std::string& msg);

}  // namespace forest_slam::core

#define FS_LOG_IMPL(level, expr)                                         \
	do {                                                                 \
		if (static_cast<int>(level) >=                                   \
			static_cast<int>(::forest_slam::core::logLevel()))          \
		{                                                                \
			std::ostringstream fs_log_os_;                               \
			fs_log_os_ << expr;                                          \
			::forest_slam::core::logMessage(level, fs_log_os_.str());    \
		}                                                                \
	} while (0)
#define FS_LOG_DEBUG(expr) FS_LOG_IMPL(::forest_slam::core::LogLevel::Debug, expr)
#define FS_LOG_INFO(expr) FS_LOG_IMPL(::forest_slam::core::LogLevel::Info, expr)
#define FS_LOG_WARN(expr) FS_LOG_IMPL(::forest_slam::core::LogLevel::Warn, expr)
#define FS_LOG_ERROR(expr) FS_LOG_IMPL(::forest_slam::core::LogLevel::Error, expr)
