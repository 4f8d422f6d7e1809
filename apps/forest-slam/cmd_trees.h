#pragma once
// `forest-slam trees`: stem detection and DBH on a cloud from any scanner.
#include <stdexcept>
#include <string>
#include <vector>

namespace forest_slam::app
{
/** A command-line mistake (main maps it to exit code 2). */
struct TreesUsageError : std::runtime_error
{
	using std::runtime_error::runtime_error;
};

/** Runs the subcommand; returns the exit code. */
int cmdTrees(const std::vector<std::string>& args, const char* usage);

}  // namespace forest_slam::app
