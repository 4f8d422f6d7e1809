// A whole `forest-slam map` job on synthetic scans (poles = stems, ground,
// walls) with a synthetic georeference: every output file is written,
// selectable, readable by the tools it is meant for, and consistent with the
// run; the report renders in headless Chromium when it is installed.
#include "../pipeline/synthetic_scans.h"
#include "test_files.h"

#include <forest_slam/io/las.h>
#include <forest_slam/io/rawlog_writer.h>
#include <forest_slam/io/tum.h>
#include <forest_slam/outputs/classification.h>
#include <forest_slam/pipeline/mapping_job.h>
#include <gtest/gtest.h>
#include <mrpt/img/CImage.h>
#include <mrpt/maps/CSimpleMap.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <octomap/OcTree.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

using namespace forest_slam;
namespace fs = std::filesystem;

namespace
{
struct Run
{
	fs::path dir;
	pipeline::MappingResult result;
	test_support::MovingSensorWorld world;
};

/** Maps 20 synthetic scans once for all tests of this file. */
const Run& run()
{
	static Run r = []
	{
		Run r;
		r.dir = test_support::freshTempDir("run");
		const int n = 20;
		io::writeTum((r.dir / "gt.tum").string(), r.world.groundTruth(n + 1));
		{
			io::RawlogWriter wr((r.dir / "run.rawlog").string());
			for (int k = 0; k < n; k++) wr.write(r.world.scan(k));
			wr.close();
		}
		std::ofstream((r.dir / "map.ini").string())
		    << "[pipeline]\npose_source = trajectory\n"
		       "[outputs]\nply = true\npcd = true\noctomap_ot = true\n"
		       "[georeference]\nmode = utm\nutm_zone = 33\nutm_north = true\n"
		       "utm_offset_e_m = 500000\nutm_offset_n_m = 6000000\n"
		       "utm_offset_h_m = 100\n";
		pipeline::MappingJob job;
		job.config_path = (r.dir / "map.ini").string();
		job.rawlog_path = (r.dir / "run.rawlog").string();
		job.poses_path = (r.dir / "gt.tum").string();
		job.out_dir = (r.dir / "out").string();
		job.progress_tty = 0;
		r.result = pipeline::runMapping(job);
		return r;
	}();
	return r;
}
using test_support::readText;
}  // namespace

TEST(OutputsRun, EveryOutputIsWritten)
{
	const auto& r = run();
	for (const char* f :
	     {"trajectory.tum", "trajectory.kitti", "keyframes.simplemap",
	      "forest.map", "map.las", "map.ply", "map.pcd", "map.bt", "map.ot",
	      "trees.csv", "trees.geojson", "dtm.asc", "report.html",
	      "run_summary.json"})
	{
		EXPECT_TRUE(fs::exists(r.dir / "out" / f)) << f;
		EXPECT_GT(fs::file_size(r.dir / "out" / f), 50u) << f;
	}
	EXPECT_EQ(r.result.outputs.size(), 14u);
	// No temp file left behind.
	for (const auto& e : fs::directory_iterator(r.dir / "out"))
		EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos)
		    << e.path();
}

TEST(OutputsRun, TrajectoryKittiMatchesTum)
{
	const auto& r = run();
	const auto tum = io::readTum((r.dir / "out/trajectory.tum").string());
	std::ifstream k(r.dir / "out/trajectory.kitti");
	size_t lines = 0;
	for (std::string line; std::getline(k, line); lines++)
	{
		std::istringstream is(line);
		Eigen::Matrix<double, 3, 4> m;
		for (int i = 0; i < 12; i++) is >> m(i / 4, i % 4);
		ASSERT_FALSE(is.fail()) << line;
		ASSERT_LT(lines, tum.size());
		EXPECT_LT((m - tum[lines].pose.matrix().topRows<3>()).norm(), 1e-5);
	}
	EXPECT_EQ(lines, tum.size());
	EXPECT_EQ(lines, 20u);
}

TEST(OutputsRun, KeyframesSimpleMapOpensInMrpt)
{
	const auto& r = run();
	mrpt::maps::CSimpleMap sm;
	ASSERT_TRUE(sm.loadFromFile((r.dir / "out/keyframes.simplemap").string()));
	// 2 m/s at 10 Hz: a keyframe every 1 m = every 5 scans.
	EXPECT_EQ(sm.size(), 4u);
	const auto& [pose, sf] = sm.get(1);
	ASSERT_TRUE(pose && sf && sf->size() == 1);
	EXPECT_NEAR(pose->getMeanVal().x(), 1.0, 1e-6);
	auto obs = sf->getObservationByClass<mrpt::obs::CObservationPointCloud>();
	ASSERT_TRUE(obs && obs->pointcloud);
	EXPECT_GT(obs->pointcloud->size(), 1000u);
}

TEST(OutputsRun, LasHasTheDenseMapGeoreferencedAndClassified)
{
	const auto& r = run();
	const auto path = (r.dir / "out/map.las").string();
	const auto las = io::readLas(path);
	const auto summary = readText(r.dir / "out/run_summary.json");
	EXPECT_NE(summary.find("\"dense_points\": " + std::to_string(las.size())),
	          std::string::npos);
	ASSERT_GT(las.size(), 10000u);
	std::map<int, size_t> classes;
	for (size_t k = 0; k < las.size(); k++)
	{
		classes[las.classification[k]]++;
		// Projected: the map (sensor path x in [0, 4], walls at +-12 m) plus
		// the offsets.
		EXPECT_NEAR(las.xyz[k].x(), 500000, 80);
		EXPECT_NEAR(las.xyz[k].y(), 6000000, 80);
	}
	// Ground (z = -1.5 in the map) and vegetation/walls above it.
	EXPECT_GT(classes[outputs::kGround], las.size() / 5);
	size_t ground_ok = 0, ground = 0;
	for (size_t k = 0; k < las.size(); k++)
		if (las.classification[k] == outputs::kGround)
			ground++, ground_ok += std::abs(las.xyz[k].z() - 98.5) < 0.2;
	EXPECT_EQ(ground_ok, ground);
	// GPS time: adjusted standard GPS time of the scans (t0 = 1000 s UNIX).
	for (size_t k = 0; k < las.size(); k += 1000)
		EXPECT_NEAR(las.gps_time_s[k], io::unixToAdjustedGpsTime(1000.0) + 1.0,
		            1.01);
	// The WKT CRS is in the file.
	const auto bytes = readText(r.dir / "out/map.las");
	EXPECT_NE(bytes.find("WGS 84 / UTM zone 33N"), std::string::npos);
}

TEST(OutputsRun, OctomapSeesThePolesAndFreeSpaceInFrontOfThem)
{
	const auto& r = run();
	octomap::OcTree tree(0.1);
	ASSERT_TRUE(tree.readBinary((r.dir / "out/map.bt").string()));
	// Pole at (5, 4), r = 0.15: its side facing the path (y = 0) is occupied
	// at the lidar's ring heights; the space between path and pole is free.
	int occ = 0, total = 0;
	for (double z = -1.0; z <= 0.3; z += 0.1)
	{
		const auto* n = tree.search(5.0, 4 - 0.15 + 0.03, z);
		total++;
		occ += n && tree.isNodeOccupied(n);
	}
	EXPECT_GE(occ, total / 2) << occ << " of " << total;
	const auto* free_node = tree.search(4.5, 2.0, -0.2);
	ASSERT_TRUE(free_node);
	EXPECT_FALSE(tree.isNodeOccupied(free_node));
}

TEST(OutputsRun, ForestMapLoadsAgainAndDtmIsTheGround)
{
	const auto& r = run();
	EXPECT_NO_THROW(
	    pipeline::loadForestMap((r.dir / "out/forest.map").string()));
	std::ifstream in(r.dir / "out/dtm.asc");
	std::map<std::string, double> hdr;
	std::string key;
	double v;
	for (int i = 0; i < 6 && in >> key >> v; i++) hdr[key] = v;
	EXPECT_GT(hdr["ncols"], 10);
	EXPECT_NEAR(hdr["xllcorner"], 500000, 80);
	// Ground z = -1.5 in the map, +100 m offset; ground points are those
	// within ground_threshold_m (0.15) of the terrain.
	std::vector<double> cells;
	while (in >> v)
		if (v != -9999)
		{
			cells.push_back(v);
			EXPECT_NEAR(v, 98.5, 0.15);
		}
	ASSERT_GT(cells.size(), 100u);
	std::nth_element(cells.begin(), cells.begin() + cells.size() / 2,
	                 cells.end());
	EXPECT_NEAR(cells[cells.size() / 2], 98.5, 0.01);
}

TEST(OutputsRun, ReportIsSelfContained)
{
	const auto& r = run();
	const auto html = readText(r.dir / "out/report.html");
	EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
	EXPECT_NE(html.find("<svg"), std::string::npos);
	EXPECT_NE(html.find("Stand table"), std::string::npos);
	EXPECT_NE(html.find("GNSS"), std::string::npos);
	EXPECT_NE(html.find("WGS 84 / UTM zone 33N"), std::string::npos);
	// Nothing to fetch: no scripts, no external resources.
	EXPECT_EQ(html.find("<script"), std::string::npos);
	EXPECT_EQ(html.find("src="), std::string::npos);
	EXPECT_EQ(html.find("href="), std::string::npos);
	EXPECT_EQ(html.find("<?xml"), std::string::npos);
}

TEST(OutputsRun, ReportRendersInHeadlessChromium)
{
	std::string browser;
	for (const char* b : {"chromium", "chromium-browser", "google-chrome"})
		if (std::system((std::string("command -v ") + b + " >/dev/null 2>&1")
		                    .c_str()) == 0)
		{
			browser = b;
			break;
		}
	if (browser.empty())
		GTEST_SKIP() << "chromium is not installed (Debian package 'chromium')";
	const auto& r = run();
	const auto png = r.dir / "report.png";
	const std::string cmd = browser +
	                        " --headless --no-sandbox --disable-gpu "
	                        "--window-size=1200,900 --screenshot=" +
	                        png.string() + " file://" +
	                        (r.dir / "out/report.html").string() +
	                        " >/dev/null 2>&1";
	ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
	mrpt::img::CImage img;
	ASSERT_TRUE(img.loadFromFile(png.string()));
	ASSERT_GT(img.getWidth(), 100u);
	// Not blank: a good share of pixels differ from the white background.
	size_t inked = 0, total = 0;
	for (unsigned y = 0; y < img.getHeight(); y += 4)
		for (unsigned x = 0; x < img.getWidth(); x += 4)
		{
			total++;
			inked += img.getAsFloat(x, y) < 0.9f;
		}
	EXPECT_GT(inked, total / 100) << inked << " of " << total;
}

TEST(OutputsConfig, UnknownOutputKeyIsAnErrorNamingIt)
{
	auto cfg =
	    core::TrackedConfig::fromText("[outputs]\nlas_format = 7\n", "x.ini");
	try
	{
		pipeline::MappingConfig::load(cfg);
		FAIL() << "no error";
	}
	catch (const core::ConfigError& e)
	{
		EXPECT_NE(std::string(e.what()).find("las_format"), std::string::npos)
		    << e.what();
	}
	auto bad =
	    core::TrackedConfig::fromText("[georeference]\nmode = gps\n", "g.ini");
	EXPECT_THROW(pipeline::MappingConfig::load(bad), core::ConfigError);
	auto order = core::TrackedConfig::fromText(
	    "[outputs]\nlow_vegetation_max_m = 3\nmedium_vegetation_max_m = 2\n",
	    "o.ini");
	EXPECT_THROW(pipeline::MappingConfig::load(order), core::ConfigError);
}

TEST(OutputsConfig, OutputsCanBeSwitchedOff)
{
	const auto& r = run();
	const auto dir = r.dir / "few";
	std::ofstream((r.dir / "few.ini").string())
	    << "[pipeline]\npose_source = trajectory\nmax_scans = 5\n"
	       "[outputs]\ntrajectory_kitti = false\nkeyframes_simplemap = false\n"
	       "las = false\noctomap_bt = false\ntrees_csv = false\n"
	       "trees_geojson = false\ndtm_asc = false\nreport_html = false\n";
	pipeline::MappingJob job;
	job.config_path = (r.dir / "few.ini").string();
	job.rawlog_path = (r.dir / "run.rawlog").string();
	job.poses_path = (r.dir / "gt.tum").string();
	job.out_dir = dir.string();
	job.progress_tty = 0;
	pipeline::runMapping(job);
	std::set<std::string> names;
	for (const auto& e : fs::directory_iterator(dir))
		names.insert(e.path().filename());
	EXPECT_EQ(names, (std::set<std::string>{"trajectory.tum", "forest.map",
	                                        "run_summary.json"}));
}

TEST(OutputsRun, SpilledDenseTilesGiveTheSameFilesAsAllInMemory)
{
	// Tiny tiles and a short dense range: tiles behind the moving sensor go
	// to the scratch file during the run. Same points, classes, DTM and
	// keyframes as the run that keeps everything in memory.
	const auto dir = test_support::freshTempDir("spill_run");
	const test_support::MovingSensorWorld world;
	const int n = 20;
	io::writeTum((dir / "gt.tum").string(), world.groundTruth(n + 1));
	{
		io::RawlogWriter wr((dir / "run.rawlog").string());
		for (int k = 0; k < n; k++) wr.write(world.scan(k));
		wr.close();
	}
	auto map = [&](const std::string& name, const std::string& outputs)
	{
		std::ofstream((dir / (name + ".ini")).string())
		    << "[pipeline]\npose_source = trajectory\n"
		       "memory_report_period_s = 0.5\n[outputs]\nply = true\n"
		       "dense_max_range_m = 8\ndense_tile_m = 1\n"
		    << outputs;
		pipeline::MappingJob job;
		job.config_path = (dir / (name + ".ini")).string();
		job.rawlog_path = (dir / "run.rawlog").string();
		job.poses_path = (dir / "gt.tum").string();
		job.out_dir = (dir / name).string();
		job.progress_tty = 0;
		return pipeline::runMapping(job);
	};
	const auto mem = map("mem", "spill_to_disk = false\n");
	const auto spill = map("spill", "spill_to_disk = true\n");
	EXPECT_EQ(mem.memory_end.spilled_mb, 0);
	EXPECT_GT(spill.memory_end.spilled_mb, 0);
	EXPECT_GE(spill.memory_curve.size(), 2u);
	const auto a = io::readLas((dir / "mem/map.las").string());
	const auto b = io::readLas((dir / "spill/map.las").string());
	ASSERT_EQ(a.size(), b.size());
	ASSERT_GT(a.size(), 1000u);
	std::multiset<std::tuple<double, double, double, int, double>> sa, sb;
	for (size_t k = 0; k < a.size(); k++)
	{
		sa.emplace(a.xyz[k].x(), a.xyz[k].y(), a.xyz[k].z(),
		           a.classification[k], a.gps_time_s[k]);
		sb.emplace(b.xyz[k].x(), b.xyz[k].y(), b.xyz[k].z(),
		           b.classification[k], b.gps_time_s[k]);
	}
	EXPECT_TRUE(sa == sb);
	EXPECT_EQ(io::readPly((dir / "mem/map.ply").string()).size(),
	          io::readPly((dir / "spill/map.ply").string()).size());
	for (const char* f : {"trajectory.tum", "trees.csv", "map.bt"})
		EXPECT_EQ(readText(dir / "mem" / f), readText(dir / "spill" / f)) << f;
	// DTM: same cells; means summed in another order may differ in the
	// last bit, not in the 3 printed decimals.
	EXPECT_EQ(readText(dir / "mem/dtm.asc"), readText(dir / "spill/dtm.asc"));
	mrpt::maps::CSimpleMap sm_a, sm_b;
	ASSERT_TRUE(sm_a.loadFromFile((dir / "mem/keyframes.simplemap").string()));
	ASSERT_TRUE(
	    sm_b.loadFromFile((dir / "spill/keyframes.simplemap").string()));
	EXPECT_EQ(sm_a.size(), sm_b.size());
	const auto summary = readText(dir / "spill/run_summary.json");
	EXPECT_NE(summary.find("\"memory\": {\"peak_rss_mb\": "),
	          std::string::npos);
	EXPECT_NE(summary.find("\"curve\": [{\"data_s\": "), std::string::npos);
}
