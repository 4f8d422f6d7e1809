#pragma once
// `forest-slam online`: map from live sensors while recording them.
#include <stdexcept>
#include <string>
#include <vector>

namespace forest_slam::app
{
/** A command-line mistake (main maps it to exit code 2). */
struct OnlineUsageError : std::runtime_error
{
	using std::runtime_error::runtime_error;
};

/** Runs the subcommand; returns the exit code. */
int cmdOnline(const std::vector<std::string>& args, const char* usage);

}  // namespace forest_slam::app
