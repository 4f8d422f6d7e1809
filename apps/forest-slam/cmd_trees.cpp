// forest-slam trees --cloud FILE.{las,ply,pcd} --out DIR [--config FILE.ini]
// Standalone tree mode (issue 7): DTM from the cloud, stems, DBH, trees.csv.
#include "cmd_trees.h"

#include <forest_slam/core/atomic_file.h>
#include <forest_slam/core/config.h>
#include <forest_slam/core/log.h>
#include <forest_slam/io/las.h>
#include <forest_slam/trees/stem_detector.h>
#include <forest_slam/trees/terrain_model.h>
#include <forest_slam/trees/tree_csv.h>
#include <forest_slam/trees/tree_options.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <stdexcept>

namespace forest_slam::app
{
int cmdTrees(const std::vector<std::string>& args, const char* usage)
{
	std::string cloud, out, config;
	for (size_t i = 0; i < args.size(); i++)
	{
		const auto& a = args[i];
		if (a == "--help")
		{
			std::cout << usage;
			return 0;
		}
		if (a != "--cloud" && a != "--out" && a != "--config")
			throw TreesUsageError("unknown option '" + a + "'");
		if (i + 1 >= args.size())
			throw TreesUsageError("option " + a + " needs a value");
		(a == "--cloud" ? cloud : a == "--out" ? out : config) = args[++i];
	}
	if (cloud.empty()) throw TreesUsageError("missing required option --cloud");
	if (out.empty()) throw TreesUsageError("missing required option --out");

	trees::TreeOptions opts;
	if (!config.empty())
	{
		// Only [trees] is read here; other sections of a mapping INI are the
		// mapping run's business, but unknown keys inside [trees] are errors.
		auto cfg = core::TrackedConfig::fromFile(config);
		opts.loadFromConfigFile(cfg, "trees");
		std::vector<std::string> sections;
		cfg.getAllSections(sections);
		for (const auto& s : sections)
			if (s != "trees") cfg.acceptSection(s);
		cfg.checkNoUnknownKeys();
	}
	const auto t0 = std::chrono::steady_clock::now();
	// A LAS file cut short (copy interrupted) keeps its complete records:
	// the trees found in them are written, the damage is named.
	const auto c = io::readCloudFile(cloud, true);
	if (!c.damage.empty())
		FS_LOG_WARN(c.damage << " -- using the " << c.size()
		                     << " points before the damage");
	if (c.size() == 0) throw std::runtime_error(cloud + ": no points");
	const auto dtm = trees::buildDtm(c.xyz, opts);
	trees::TreeDetectionStats st;
	const auto found = trees::detectTrees(c.xyz, dtm, opts, &st);
	const auto records = trees::toRecords(found);
	core::ensureDirectory(out);
	const std::string csv = out + "/trees.csv";
	trees::writeTreesCsv(csv, records);
	const double secs =
	    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
	        .count();

	std::printf(
	    "cloud: %zu points; %zu slices, %zu slice clusters, %zu stem sections, "
	    "%zu chains\n",
	    c.size(), st.slices, st.slice_clusters, st.sections, st.chains);
	std::printf(
	    "rejected: %zu too few slices, %zu taper/lean/straightness, %zu < "
	    "min_tree_points, %zu duplicates\n",
	    st.rejected_short, st.rejected_shape, st.rejected_points,
	    st.rejected_duplicate);
	std::printf("DBH from the solid-ring fit (foliage around the stem): %zu\n",
	            st.solid_rings);
	if (records.empty())
		std::printf("trees: 0\n");
	else
	{
		double sum = 0, lo = 1e9, hi = 0;
		for (const auto& r : records)
			sum += r.dbh_m, lo = std::min(lo, r.dbh_m),
			                hi = std::max(hi, r.dbh_m);
		std::printf("trees: %zu, DBH mean %.1f cm, min %.1f cm, max %.1f cm\n",
		            records.size(), 100 * sum / records.size(), 100 * lo,
		            100 * hi);
	}
	std::printf("time: %.2f s\nwrote %s\n", secs, csv.c_str());
	// Like `map` on a damaged rawlog: outputs written, exit status 1.
	if (!c.damage.empty())
	{
		std::fprintf(stderr, "forest-slam: input damaged: %s\n",
		             c.damage.c_str());
		return 1;
	}
	return 0;
}

}  // namespace forest_slam::app
