// Replays the committed fuzz corpus (tests/fuzz/corpus/<target>/*) and the
// crash reproducers (tests/fuzz/regressions/<target>/*) through the fuzz
// entry functions in the normal build, so that every input that once found a
// bug, and the seeds, stay covered in CI without clang or libFuzzer.
#include "fuzz_targets.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

namespace fs = std::filesystem;

namespace
{
using Entry = int (*)(const uint8_t*, size_t);

size_t replay(const std::string& target, Entry fn)
{
	size_t n = 0;
	for (const char* kind : {"corpus", "regressions"})
	{
		const fs::path dir =
		    fs::path(FOREST_SLAM_SOURCE_DIR) / "tests/fuzz" / kind / target;
		if (!fs::is_directory(dir)) continue;
		std::vector<fs::path> files;
		for (const auto& e : fs::directory_iterator(dir))
			if (e.is_regular_file()) files.push_back(e.path());
		std::sort(files.begin(), files.end());
		for (const auto& f : files)
		{
			std::ifstream in(f, std::ios::binary);
			const std::vector<uint8_t> d((std::istreambuf_iterator<char>(in)),
			                             std::istreambuf_iterator<char>());
			SCOPED_TRACE(f.string());
			EXPECT_NO_THROW(fn(d.data(), d.size()));
			n++;
		}
	}
	return n;
}
}  // namespace

TEST(FuzzCorpus, Las)
{
	EXPECT_GE(replay("las", forest_slam::fuzz::fuzzLas), 3u);
}

TEST(FuzzCorpus, RosMessages)
{
	EXPECT_GE(replay("ros_messages", forest_slam::fuzz::fuzzRosMessages), 5u);
}

TEST(FuzzCorpus, Ini)
{
	EXPECT_GE(replay("ini", forest_slam::fuzz::fuzzIni), 3u);
}
