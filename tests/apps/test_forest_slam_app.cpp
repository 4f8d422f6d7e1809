// End-to-end: run the forest-slam binary as a user would.
#include <forest_slam/io/tum.h>
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;

namespace
{
struct Run
{
	int code = -1;
	std::string output;  // stdout + stderr
};

/** `env`: assignments put before the command, e.g. "A=1 ". */
Run run(const std::string& args, const std::string& env = "")
{
	const std::string cmd = env + std::string(FOREST_SLAM_BIN_DIR) +
	                        "/forest-slam " + args + " 2>&1";
	Run r;
	FILE* p = popen(cmd.c_str(), "r");
	std::array<char, 4096> buf;
	size_t n;
	while ((n = fread(buf.data(), 1, buf.size(), p)) > 0)
		r.output.append(buf.data(), n);
	const int st = pclose(p);
	r.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
	return r;
}

std::string tmpDir(const std::string& name)
{
	const auto d = fs::temp_directory_path() /
	               ("fs_app_" + std::to_string(::getpid()) + "_" + name);
	fs::create_directories(d);
	return d.string();
}
}  // namespace

TEST(ForestSlamApp, HelpAndUsageErrors)
{
	auto r = run("--help");
	EXPECT_EQ(r.code, 0);
	EXPECT_NE(r.output.find("forest-slam map"), std::string::npos);
	EXPECT_EQ(run("").code, 2);
	EXPECT_EQ(run("frobnicate").code, 2);
	r = run("map --config ini/vlp16-handheld.ini --bogus 1");
	EXPECT_EQ(r.code, 2);
	EXPECT_NE(r.output.find("--bogus"), std::string::npos);
	r = run("map --config ini/vlp16-handheld.ini");
	EXPECT_EQ(r.code, 2);
	EXPECT_NE(r.output.find("--rawlog"), std::string::npos);
	EXPECT_EQ(run("map --help").code, 0);
}

TEST(ForestSlamApp, ShippedConfigsDumpCleanly)
{
	for (const char* ini : {"ini/vlp16-handheld.ini", "ini/vlp16-robot.ini"})
	{
		const auto r = run(std::string("config --dump --config ") + ini);
		EXPECT_EQ(r.code, 0) << ini << ": " << r.output;
		EXPECT_NE(r.output.find("[forest_map]"), std::string::npos);
		EXPECT_NE(r.output.find("submap_size_m"), std::string::npos);
	}
}

TEST(ForestSlamApp, TypoInIniIsAnErrorNamingFileSectionKey)
{
	const auto d = tmpDir("typo");
	const auto ini = d + "/typo.ini";
	std::ofstream(ini) << "[forest_map]\nedge_voxle_m = 0.1\n";
	auto r = run("config --dump --config " + ini);
	EXPECT_EQ(r.code, 1);
	EXPECT_NE(r.output.find(ini), std::string::npos) << r.output;
	EXPECT_NE(r.output.find("edge_voxle_m"), std::string::npos) << r.output;
	EXPECT_NE(r.output.find("[forest_map]"), std::string::npos) << r.output;
	std::ofstream(ini) << "[forest_map]\nedge_voxel_m = zero\n";
	r = run("config --dump --config " + ini);
	EXPECT_EQ(r.code, 1);
	EXPECT_NE(r.output.find("edge_voxel_m"), std::string::npos) << r.output;
	r = run("map --config " + ini + " --rawlog /nonexistent.rawlog --out " + d);
	EXPECT_EQ(r.code, 1);
}

TEST(ForestSlamApp, MapsARealMrptRawlog)
{
	const auto d = tmpDir("real");
	const auto ini = d + "/real.ini";
	// The MRPT sample labels its scan "Velodyne1_SCAN".
	std::ofstream(ini) << "[pipeline]\nlidar_label = Velodyne1_SCAN\n";
	const std::string rawlog = std::string(FOREST_SLAM_SHARED_DIR) +
	                           "/data/mrpt/rot_scan_velodyne.rawlog";
	const auto out = d + "/out";
	const auto r = run("map --config " + ini + " --rawlog " + rawlog +
	                   " --out " + out + " --progress log");
	ASSERT_EQ(r.code, 0) << r.output;
	EXPECT_NE(r.output.find("1 mapped of 1"), std::string::npos) << r.output;
	const auto traj = forest_slam::io::readTum(out + "/trajectory.tum");
	ASSERT_EQ(traj.size(), 1u);
	EXPECT_NEAR(traj[0].t_s, 1519637061.085268, 1e-3);
	EXPECT_TRUE(traj[0].pose.isApprox(Eigen::Isometry3d::Identity()));
	std::ifstream js(out + "/run_summary.json");
	std::stringstream ss;
	ss << js.rdbuf();
	EXPECT_NE(ss.str().find("\"scans_mapped\": 1"), std::string::npos)
	    << ss.str();
	EXPECT_GT(fs::file_size(out + "/forest.map"), 10000u);
	// No temporary files left behind.
	for (const auto& e : fs::directory_iterator(out))
		EXPECT_EQ(e.path().string().find(".tmp."), std::string::npos)
		    << e.path();
}

// forest-slam re-executes itself with glibc's malloc on transparent huge
// pages (core::useHugePages), unless told not to; run_summary.json says
// which way the run went.
TEST(ForestSlamApp, HeapOnHugePagesUnlessTurnedOff)
{
	std::ifstream mode("/sys/kernel/mm/transparent_hugepage/enabled");
	std::string line;
	if (!mode || !std::getline(mode, line) ||
	    line.find("[never]") != std::string::npos)
		GTEST_SKIP() << "the kernel has no transparent huge pages";
	const auto d = tmpDir("huge");
	const auto ini = d + "/real.ini";
	std::ofstream(ini) << "[pipeline]\nlidar_label = Velodyne1_SCAN\n";
	const std::string rawlog = std::string(FOREST_SLAM_SHARED_DIR) +
	                           "/data/mrpt/rot_scan_velodyne.rawlog";
	for (const bool on : {true, false})
	{
		const auto out = d + (on ? "/on" : "/off");
		// The user's own tunables are kept alongside.
		const auto r =
		    run("map --config " + ini + " --rawlog " + rawlog + " --out " +
		            out + " --progress log",
		        on ? "env -u FOREST_SLAM_HUGE_PAGES "
		             "GLIBC_TUNABLES=glibc.malloc.check=0 "
		           : "env -u GLIBC_TUNABLES FOREST_SLAM_HUGE_PAGES=0 ");
		ASSERT_EQ(r.code, 0) << r.output;
		std::ifstream js(out + "/run_summary.json");
		std::stringstream ss;
		ss << js.rdbuf();
		EXPECT_NE(ss.str().find(on ? "\"heap_huge_pages\": true"
		                           : "\"heap_huge_pages\": false"),
		          std::string::npos)
		    << ss.str();
	}
}
