#include <forest_slam/core/config.h>
#include <gtest/gtest.h>

using forest_slam::core::ConfigError;
using forest_slam::core::TrackedConfig;

namespace
{
struct Opts
{
	double voxel_m = 0.2;
	int count = 3;
	bool flag = false;
	std::string name = "a";
	std::vector<double> v;
	void load(const mrpt::config::CConfigFileBase& c, const std::string& s)
	{
		FS_LOAD(c, s, voxel_m);
		FS_LOAD(c, s, count);
		FS_LOAD(c, s, flag);
		FS_LOAD(c, s, name);
		FS_LOAD(c, s, v);
	}
};

std::string errorOf(const std::function<void()>& f)
{
	try
	{
		f();
	}
	catch (const ConfigError& e)
	{
		return e.what();
	}
	return "";
}
}  // namespace

TEST(Config, LoadsValuesAndKeepsDefaults)
{
	auto cfg = TrackedConfig::fromText(
	    "[m]\nvoxel_m = 0.5\nflag = true\nv = 1, 2.5, 3\n", "test.ini");
	Opts o;
	o.load(cfg, "m");
	EXPECT_DOUBLE_EQ(o.voxel_m, 0.5);
	EXPECT_EQ(o.count, 3);
	EXPECT_TRUE(o.flag);
	EXPECT_EQ(o.name, "a");
	ASSERT_EQ(o.v.size(), 3u);
	EXPECT_DOUBLE_EQ(o.v[1], 2.5);
	EXPECT_NO_THROW(cfg.checkNoUnknownKeys());
}

TEST(Config, UnknownKeyNamesFileSectionAndKey)
{
	auto cfg =
	    TrackedConfig::fromText("[m]\nvoxel_m = 0.5\nvoxle_m = 1\n", "my.ini");
	Opts o;
	o.load(cfg, "m");
	const auto msg = errorOf([&] { cfg.checkNoUnknownKeys(); });
	EXPECT_NE(msg.find("my.ini"), std::string::npos) << msg;
	EXPECT_NE(msg.find("[m]"), std::string::npos) << msg;
	EXPECT_NE(msg.find("voxle_m"), std::string::npos) << msg;
}

TEST(Config, UnknownSectionIsAnError)
{
	auto cfg = TrackedConfig::fromText("[m]\nvoxel_m = 0.5\n[mapp]\nx = 1\n",
	                                   "my.ini");
	Opts o;
	o.load(cfg, "m");
	const auto msg = errorOf([&] { cfg.checkNoUnknownKeys(); });
	EXPECT_NE(msg.find("unknown section [mapp]"), std::string::npos) << msg;
	cfg.acceptSection("mapp");
	EXPECT_NO_THROW(cfg.checkNoUnknownKeys());
}

TEST(Config, BadValuesAreErrorsWithContext)
{
	for (const char* text :
	     {"[m]\nvoxel_m = abc\n", "[m]\ncount = 2.5\n", "[m]\nflag = maybe\n",
	      "[m]\nvoxel_m = nan\n", "[m]\nv = 1, x\n"})
	{
		auto cfg = TrackedConfig::fromText(text, "bad.ini");
		Opts o;
		const auto msg = errorOf([&] { o.load(cfg, "m"); });
		EXPECT_NE(msg.find("bad.ini: [m]"), std::string::npos)
		    << text << " -> " << msg;
		EXPECT_NE(msg.find("expected"), std::string::npos) << msg;
	}
}

TEST(Config, SectionAndKeyMatchingIsCaseInsensitive)
{
	auto cfg = TrackedConfig::fromText("[M]\nVoxel_M = 0.7\n", "c.ini");
	Opts o;
	o.load(cfg, "m");
	EXPECT_DOUBLE_EQ(o.voxel_m, 0.7);
	EXPECT_NO_THROW(cfg.checkNoUnknownKeys());
}

TEST(Config, MissingFileIsAnError)
{
	const auto msg =
	    errorOf([] { TrackedConfig::fromFile("/nonexistent/x.ini"); });
	EXPECT_NE(msg.find("/nonexistent/x.ini"), std::string::npos);
}

TEST(Config, PreprocessorErrorsNameTheConfig)
{
	// MRPT's INI preprocessor throws std::runtime_error naming a line only
	// (a fuzz_ini finding); it reaches the user as a ConfigError naming the
	// file.
	try
	{
		TrackedConfig::fromText("[pipeline]\nmax_scans = $env{false\n",
		                        "rig.ini");
		FAIL() << "no error";
	}
	catch (const ConfigError& e)
	{
		EXPECT_NE(std::string(e.what()).find("rig.ini"), std::string::npos)
		    << e.what();
	}
}
