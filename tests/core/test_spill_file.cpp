// The scratch file of long runs: blobs read back as written, no name left
// in the folder, a clear error for a folder that cannot take one.
#include "../support/file_size_limit.h"

#include <forest_slam/core/spill_file.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <numeric>
#include <string>
#include <vector>

using namespace forest_slam;
namespace fs = std::filesystem;

TEST(SpillFile, BlobsReadBackAsWrittenAndNoFileLeftInTheFolder)
{
	const fs::path dir =
	    fs::temp_directory_path() /
	    ("fs_spill_" +
	     std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
	     "_" + std::to_string(getpid()));
	fs::create_directories(dir);
	{
		core::SpillFile f(dir.string());
		std::vector<double> a(100000);
		std::iota(a.begin(), a.end(), 0.5);
		const std::vector<int> b = {7, -3, 12};
		const uint64_t oa = f.appendVector(a), ob = f.appendVector(b);
		EXPECT_EQ(oa, 0u);
		EXPECT_EQ(ob, a.size() * sizeof(double));
		EXPECT_EQ(f.size(), ob + b.size() * sizeof(int));
		std::vector<int> b2;
		f.readVector(ob, b.size(), b2);
		EXPECT_EQ(b2, b);
		std::vector<double> a2;
		f.readVector(oa, a.size(), a2);
		EXPECT_EQ(a2, a);
		EXPECT_THROW(f.read(f.size() - 2, a2.data(), 4), std::logic_error);
		// Unnamed: nothing to clean up, even after kill -9.
		EXPECT_TRUE(fs::is_empty(dir));
	}
	fs::remove_all(dir);
}

// A blob rewritten after every revisit: the old copies' blocks go back to
// the file system, the other blobs read back unchanged.
TEST(SpillFile, DiscardedBlobsGiveTheirSpaceBack)
{
	core::SpillFile f(fs::temp_directory_path().string());
	const std::vector<int> keep = {1, 2, 3, 4};
	std::vector<char> big(8 << 20, 'x');
	const uint64_t o_keep = f.appendVector(keep);
	uint64_t o_big = f.appendVector(big);
	for (int rewrite = 0; rewrite < 5; rewrite++)
	{
		big[rewrite] = char('a' + rewrite);
		const uint64_t o_new = f.appendVector(big);
		f.discard(o_big, big.size());
		o_big = o_new;
	}
	EXPECT_EQ(f.size(), keep.size() * sizeof(int) + 6 * big.size());
	EXPECT_EQ(f.liveBytes(), keep.size() * sizeof(int) + big.size());
	// ext4, xfs, tmpfs punch holes; the blocks of five copies are free.
	EXPECT_LT(f.allocatedBytes(), 2 * big.size() + (1 << 20))
	    << "the discarded copies still take disk space";
	std::vector<int> k2;
	f.readVector(o_keep, keep.size(), k2);
	EXPECT_EQ(k2, keep);
	std::vector<char> b2;
	f.readVector(o_big, big.size(), b2);
	EXPECT_EQ(b2, big);
	EXPECT_THROW(f.discard(f.size() - 2, 4), std::logic_error);
}

TEST(SpillFile, MissingFolderIsAClearError)
{
	try
	{
		core::SpillFile f("/nonexistent/forest-slam-spill");
		FAIL() << "no error";
	}
	catch (const std::runtime_error& e)
	{
		EXPECT_NE(std::string(e.what()).find("/nonexistent/forest-slam-spill"),
		          std::string::npos)
		    << e.what();
	}
}

TEST(SpillFile, AFullDiskIsAClearError)
{
	core::SpillFile f;
	std::string what;
	{
		const test::FileSizeLimit full_disk(4096);
		ASSERT_TRUE(full_disk.ok());
		try
		{
			f.appendVector(std::vector<char>(8192, 'x'));
		}
		catch (const std::runtime_error& e)
		{
			what = e.what();
		}
	}
	EXPECT_EQ(what.rfind("cannot write the spill file in '", 0), 0u) << what;
	EXPECT_NE(what.find("$TMPDIR"), std::string::npos) << what;
}
