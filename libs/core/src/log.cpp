#include <forest_slam/core/log.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <set>
#include <stdexcept>

namespace forest_slam::core
{
namespace
{
std::atomic<int> g_level{static_cast<int>(LogLevel::Info)};
std::mutex g_mutex;
std::set<std::string> g_once_keys;
const auto g_start = std::chrono::steady_clock::now();
}  // namespace

void setLogLevel(LogLevel level) { g_level = static_cast<int>(level); }
LogLevel logLevel() { return static_cast<LogLevel>(g_level.load()); }

LogLevel parseLogLevel(const std::string& name)
{
	if (name == "debug") return LogLevel::Debug;
	if (name == "info") return LogLevel::Info;
	if (name == "warn") return LogLevel::Warn;
	if (name == "error") return LogLevel::Error;
	if (name == "quiet") return LogLevel::Quiet;
	throw std::invalid_argument(
		"unknown log level '" + name + "' (expected debug|info|warn|error|quiet)");
}

void logMessage(LogLevel level, const std::string& msg)
{
	if (static_cast<int>(level) < g_level.load()) return;
	static const char* names[] = {"debug", "info", "WARN", "ERROR", ""};
	const double t = std::chrono::duration<double>(
						 std::chrono::steady_clock::now() - g_start)
						 .count();
	std::lock_guard<std::mutex> lk(g_mutex);
	std::fprintf(stderr, "[%8.3f] %-5s %s\n", t,
				 names[static_cast<int>(level)], msg.c_str());
}

void logOnce(LogLevel level, const std::string& key, const std::string& msg)
{
	{
		std::lock_guard<std::mutex> lk(g_mutex);
		if (!g_once_keys.insert(key).second) return;
	}
	logMessage(level, msg);
}

}  // namespace forest_slam::core
