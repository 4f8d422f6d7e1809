#pragma once
// File helpers shared by the output tests.
#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace forest_slam::test_support
{
/** A fresh, empty folder under the system temp folder, unique per process. */
inline std::filesystem::path freshTempDir(const std::string& name)
{
	const auto d = std::filesystem::temp_directory_path() /
	               ("fs_outputs_" + name + "_" + std::to_string(::getpid()));
	std::filesystem::remove_all(d);
	std::filesystem::create_directories(d);
	return d;
}

inline std::string readText(const std::filesystem::path& p)
{
	std::ifstream f(p, std::ios::binary);
	std::stringstream ss;
	ss << f.rdbuf();
	return ss.str();
}
}  // namespace forest_slam::test_support
