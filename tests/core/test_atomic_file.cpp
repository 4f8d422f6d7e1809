#include <forest_slam/core/atomic_file.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;
using namespace forest_slam::core;

namespace
{
std::string slurp(const std::string& p)
{
	std::ifstream f(p);
	std::stringstream ss;
	ss << f.rdbuf();
	return ss.str();
}
std::string tmpDir()
{
	auto d = fs::temp_directory_path() / ("fs_atomic_" + std::to_string(::getpid()));
	fs::create_directories(d);
	return d.string();
}
}  // namespace

TEST(AtomicFile, CommitReplacesAndLeavesNoTemp)
{
	const auto dir = tmpDir();
	const auto p = dir + "/out.txt";
	writeFileAtomically(p, [](std::ostream& os) { os << "one"; });
	EXPECT_EQ(slurp(p), "one");
	writeFileAtomically(p, [](std::ostream& os) { os << "two"; });
	EXPECT_EQ(slurp(p), "two");
	EXPECT_FALSE(fs::exists(tempPathFor(p)));
}

TEST(AtomicFile, FailureKeepsPreviousVersion)
{
	const auto dir = tmpDir();
	const auto p = dir + "/keep.txt";
	writeFileAtomically(p, [](std::ostream& os) { os << "good"; });
	EXPECT_THROW(writeFileAtomically(p,
									 [](std::ostream& os) {
										 os << "half";
										 throw std::runtime_error("crash");
									 }),
				 std::runtime_error);
	EXPECT_EQ(slurp(p), "good");
	EXPECT_FALSE(fs::exists(tempPathFor(p)));
}

TEST(AtomicFile, UnwritableDirectoryNamesThePath)
{
	try
	{
		AtomicFileWriter w("/nonexistent_dir/x.txt");
		FAIL() << "expected an exception";
	}
	catch (const std::runtime_error& e)
	{
		EXPECT_NE(std::string(e.what()).find("/nonexistent_dir/x.txt"), std::string::npos);
	}
}

TEST(AtomicFile, EnsureDirectoryCreatesParents)
{
	const auto d = tmpDir() + "/a/b/c";
	ensureDirectory(d);
	EXPECT_TRUE(fs::is_directory(d));
	EXPECT_THROW(ensureDirectory("/proc/forbidden/x"), std::runtime_error);
}
