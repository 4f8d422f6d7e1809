// Replays a run's tree-layer column detections from the files that
// [trees] layer_dump_dir made them write (trees::writeColumnInput): the
// DTM and the stem detection of every column, on one thread, each column
// `--repeat` times (its fastest time kept). Prints one line per column and
// the totals; `--trees-csv` writes the trees found (trees.csv columns) for
// forest-eval. The same code as the run's detection, timed alone: a change
// to the detection is measured here in seconds, not in a noisy 2-minute run.
//
//   bench_tree_detection DIR [--config INI] [--repeat N] [--trees-csv FILE]
#include <forest_slam/core/config.h>
#include <forest_slam/trees/column_input.h>
#include <forest_slam/trees/terrain_model.h>
#include <forest_slam/trees/tree_csv.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

using namespace forest_slam;

namespace
{
int usage(const std::string& error)
{
	std::cerr << "bench_tree_detection: " << error << "\n"
	          << "Usage: bench_tree_detection DIR [--config INI] [--repeat N] "
	             "[--trees-csv FILE]\n"
	             "  DIR          files column_*.bin of a run with [trees] "
	             "layer_dump_dir = DIR\n"
	             "  --config     INI whose [trees] section the run used "
	             "(default: the defaults)\n"
	             "  --repeat N   time every column N times, keep the fastest "
	             "(default 1)\n"
	             "  --trees-csv  write the trees found (trees.csv columns)\n";
	return 2;
}

double percentile(std::vector<double> v, double q)
{
	if (v.empty()) return 0;
	std::sort(v.begin(), v.end());
	return v[std::min(v.size() - 1, size_t(q * double(v.size())))];
}
}  // namespace

int main(int argc, char** argv)
{
	std::string dir, config, trees_csv;
	int repeat = 1;
	for (int i = 1; i < argc; i++)
	{
		const std::string a = argv[i];
		auto value = [&]() -> std::string
		{
			if (i + 1 >= argc)
				throw std::invalid_argument(a + " needs a value");
			return argv[++i];
		};
		try
		{
			if (a == "--config")
				config = value();
			else if (a == "--repeat")
			{
				const std::string v = value();
				size_t used = 0;
				try
				{
					repeat = std::stoi(v, &used);
				}
				catch (const std::exception&)
				{
				}
				if (used == 0 || used != v.size())
					return usage("--repeat needs a whole number, got '" + v +
					             "'");
			}
			else if (a == "--trees-csv")
				trees_csv = value();
			else if (!a.empty() && a[0] == '-')
				return usage("unknown option " + a);
			else if (dir.empty())
				dir = a;
			else
				return usage("one directory only");
		}
		catch (const std::exception& e)
		{
			return usage(e.what());
		}
	}
	if (dir.empty()) return usage("no directory given");
	if (repeat < 1) return usage("--repeat must be >= 1");
	try
	{
		trees::TreeOptions o;
		if (!config.empty())
		{
			const auto cfg = core::TrackedConfig::fromFile(config);
			o.loadFromConfigFile(cfg, "trees");
		}
		std::vector<std::string> files;
		for (const auto& e : std::filesystem::directory_iterator(dir))
		{
			const std::string name = e.path().filename().string();
			if (name.rfind("column_", 0) == 0 && e.path().extension() == ".bin")
				files.push_back(e.path().string());
		}
		std::sort(files.begin(), files.end());
		if (files.empty())
			throw std::runtime_error("no column_*.bin files in " + dir);
		std::vector<map::TreeRecord> all;
		std::vector<double> column_ms;
		size_t points = 0, seg_points = 0;
		std::printf("%-24s %9s %9s %6s %9s\n", "column", "points", "seg_pts",
		            "trees", "ms");
		for (const auto& f : files)
		{
			const trees::ColumnInput in = trees::readColumnInput(f);
			std::vector<map::TreeRecord> found;
			double best_ms = 1e300;
			for (int r = 0; r < repeat; r++)
			{
				const auto t0 = std::chrono::steady_clock::now();
				if (!in.ground.empty() && !in.pts.empty())
				{
					const trees::TerrainModel dtm =
					    trees::buildDtm(in.ground, o);
					found = trees::detectColumnTrees(in, dtm, o);
				}
				best_ms =
				    std::min(best_ms, std::chrono::duration<double, std::milli>(
				                          std::chrono::steady_clock::now() - t0)
				                          .count());
			}
			std::printf("%-24s %9zu %9zu %6zu %9.1f\n",
			            std::filesystem::path(f).filename().c_str(),
			            in.pts.size(), in.seg.pts.size(), found.size(),
			            best_ms);
			points += in.pts.size(), seg_points += in.seg.pts.size();
			column_ms.push_back(best_ms);
			all.insert(all.end(), found.begin(), found.end());
		}
		double total = 0, dbh_sum = 0;
		for (double v : column_ms) total += v;
		for (size_t i = 0; i < all.size(); i++)
			all[i].id = uint32_t(i + 1), dbh_sum += all[i].dbh_m;
		std::printf(
		    "columns %zu, points %zu, segmented points %zu\n"
		    "trees %zu (sum of DBH %.6f m)\n"
		    "detection %.3f s on one thread; per column median %.1f ms, p95 "
		    "%.1f ms, max %.1f ms\n",
		    files.size(), points, seg_points, all.size(), dbh_sum, total / 1e3,
		    percentile(column_ms, 0.5), percentile(column_ms, 0.95),
		    *std::max_element(column_ms.begin(), column_ms.end()));
		if (!trees_csv.empty()) trees::writeTreesCsv(trees_csv, all);
	}
	catch (const std::exception& e)
	{
		std::cerr << "bench_tree_detection: error: " << e.what() << "\n";
		return 1;
	}
	return 0;
}
