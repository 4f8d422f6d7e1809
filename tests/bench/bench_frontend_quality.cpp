// Front-end quality against forest-sim ground truth, with per-stage times:
// ground precision/recall, cluster tree mixing, edges on stems/branches
// (definitions in tests/frontend/frontend_scorer.h and doc/frontend.md).
// Usage: bench_frontend_quality SIM_DIR [--ini FILE] [--first N] [--scans N]
//   SIM_DIR holds forest-sim's run.rawlog and gt_trajectory.tum; FILE may
//   hold [ground] [cluster] [features] sections (other sections ignored).
#include <forest_slam/core/config.h>
#include <frontend_scorer.h>

#include <cstdio>
#include <cstring>
#include <string>

using namespace forest_slam;

int main(int argc, char** argv)
{
	if (argc < 2)
	{
		std::fprintf(stderr,
		             "usage: bench_frontend_quality SIM_DIR [--ini FILE] "
		             "[--first N] [--scans N]\n");
		return 2;
	}
	const std::string dir = argv[1];
	std::string ini;
	size_t first = 0, scans = SIZE_MAX;
	for (int a = 2; a + 1 < argc; a += 2)
	{
		if (!std::strcmp(argv[a], "--ini"))
			ini = argv[a + 1];
		else if (!std::strcmp(argv[a], "--first"))
			first = std::stoul(argv[a + 1]);
		else if (!std::strcmp(argv[a], "--scans"))
			scans = std::stoul(argv[a + 1]);
		else
		{
			std::fprintf(stderr, "unknown option %s\n", argv[a]);
			return 2;
		}
	}
	try
	{
		frontend_eval::FrontEndOptions o;
		if (!ini.empty())
		{
			auto cfg = core::TrackedConfig::fromFile(ini);
			o.ground.loadFromConfigFile(cfg, "ground");
			o.cluster.loadFromConfigFile(cfg, "cluster");
			o.features.loadFromConfigFile(cfg, "features");
		}
		const auto s = frontend_eval::scoreRawlog(
		    dir + "/run.rawlog", dir + "/gt_trajectory.tum", o, first, scans);
		std::printf("%s", s.summary().c_str());
	}
	catch (const std::exception& e)
	{
		std::fprintf(stderr, "bench_frontend_quality: %s\n", e.what());
		return 1;
	}
	return 0;
}
