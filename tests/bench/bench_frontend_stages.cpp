// Google Benchmark of the front-end stages, one VLP-16 scan per iteration:
// ground lattice labelling, hierarchical k-means of the non-ground points,
// cluster-aware feature extraction. Targets (issue 5, one core): ground
// <= 1 ms, clustering <= 3 ms, features <= 1 ms per scan.
// Scans: the real VLP-16 scan of ../shared/data/mrpt/rot_scan_velodyne.rawlog
// ("real") and, if FOREST_SLAM_BENCH_SIM names a forest-sim run directory
// (scripts/bench-frontend.sh passes build/bench-sim/handheld), a forest scan
// of it ("forest"), which has about twice as many returns. Stage options:
// the [ground] [cluster] [features] sections of the shipped
// ini/vlp16-handheld.ini (the robot INI has the same ones), or of FILE.
// Usage: bench_frontend_stages [--ini FILE] [--benchmark_* flags]
#include <benchmark/benchmark.h>
#include <forest_slam/cluster/hierarchical_kmeans.h>
#include <forest_slam/core/config.h>
#include <forest_slam/core/scan_points.h>
#include <forest_slam/features/feature_extractor.h>
#include <forest_slam/ground/ground_lattice.h>
#include <forest_slam/io/rawlog_reader.h>
#include <mrpt/obs/CObservationRotatingScan.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <string>

using namespace forest_slam;

namespace
{
/** One scan prepared for every stage (the inputs each stage gets in the
 * pipeline: ground labels for clustering, clusters for features). */
struct Prepared
{
	std::vector<Eigen::Vector3f> xyz, non_ground;
	std::vector<uint32_t> non_ground_idx;
	std::vector<features::FeatureInputPoint> fin;
};

/** The stage options the benchmarks run with. */
struct StageOptions
{
	ground::GroundOptions ground;
	cluster::ClusterOptions cluster;
	features::FeatureOptions features;
};
StageOptions& stageOptions()
{
	static StageOptions o;
	return o;
}

core::ScanPoints readScan(const std::string& path, size_t index)
{
	io::RawlogReader r(path);
	size_t k = 0;
	while (auto o = r.next())
	{
		auto s =
		    std::dynamic_pointer_cast<mrpt::obs::CObservationRotatingScan>(o);
		if (!s || k++ < index) continue;
		if (s->lidarModel.empty() || s->lidarModel == "UNKNOWN_SCANNER")
			s->lidarModel = "VLP16";
		return core::unpackRotatingScan(*s);
	}
	throw std::runtime_error("no rotating scan #" + std::to_string(index) +
	                         " in " + path);
}

Prepared prepare(const core::ScanPoints& sp)
{
	Prepared p;
	for (const auto& q : sp.points)
	{
		p.xyz.emplace_back(q.x, q.y, q.z);
		features::FeatureInputPoint f;
		f.xyz = p.xyz.back();
		f.ring = q.ring;
		f.column = q.column;
		p.fin.push_back(f);
	}
	ground::GroundLattice g(stageOptions().ground);
	const auto lab = g.labelScan(p.xyz, Eigen::Vector3d::Zero());
	for (size_t i = 0; i < lab.size(); i++)
	{
		p.fin[i].ground = lab[i] != 0;
		if (!lab[i])
		{
			p.non_ground.push_back(p.xyz[i]);
			p.non_ground_idx.push_back(static_cast<uint32_t>(i));
		}
	}
	const auto cl =
	    cluster::hierarchicalKMeans(p.non_ground, stageOptions().cluster);
	for (size_t k = 0; k < p.non_ground_idx.size(); k++)
		p.fin[p.non_ground_idx[k]].cluster = cl.cluster[k];
	return p;
}

std::map<std::string, Prepared>& scans()
{
	static std::map<std::string, Prepared> s;
	return s;
}

void BM_Ground(benchmark::State& st, const std::string& name)
{
	const auto& p = scans().at(name);
	// Kept across scans, as in the pipeline.
	ground::GroundLattice g(stageOptions().ground);
	size_t n_ground = 0;
	for (auto _ : st)
	{
		const auto lab = g.labelScan(p.xyz, Eigen::Vector3d::Zero());
		benchmark::DoNotOptimize(lab.data());
		n_ground = std::count(lab.begin(), lab.end(), 1);
	}
	st.counters["points"] = static_cast<double>(p.xyz.size());
	st.counters["ground"] = static_cast<double>(n_ground);
}

void BM_Cluster(benchmark::State& st, const std::string& name)
{
	const auto& p = scans().at(name);
	size_t n = 0;
	for (auto _ : st)
	{
		const auto cl =
		    cluster::hierarchicalKMeans(p.non_ground, stageOptions().cluster);
		benchmark::DoNotOptimize(cl.cluster.data());
		n = cl.clusterCount();
	}
	st.counters["points"] = static_cast<double>(p.non_ground.size());
	st.counters["clusters"] = static_cast<double>(n);
}

void BM_Features(benchmark::State& st, const std::string& name)
{
	const auto& p = scans().at(name);
	size_t e = 0, pl = 0;
	for (auto _ : st)
	{
		const auto f =
		    features::extractFeatures(p.fin, stageOptions().features);
		benchmark::DoNotOptimize(f.edges.data());
		e = f.edges.size();
		pl = f.planar.size();
	}
	st.counters["points"] = static_cast<double>(p.fin.size());
	st.counters["edges"] = static_cast<double>(e);
	st.counters["planar"] = static_cast<double>(pl);
}
}  // namespace

int main(int argc, char** argv)
{
	benchmark::Initialize(&argc, argv);
	std::string ini = "ini/vlp16-handheld.ini";
	for (int a = 1; a < argc; a++)
	{
		if (!std::strcmp(argv[a], "--ini") && a + 1 < argc)
			ini = argv[++a];
		else
		{
			std::fprintf(stderr,
			             "usage: bench_frontend_stages [--ini FILE] "
			             "[--benchmark_* flags]\n");
			return 2;
		}
	}
	try
	{
		auto cfg = core::TrackedConfig::fromFile(ini);
		stageOptions().ground.loadFromConfigFile(cfg, "ground");
		stageOptions().cluster.loadFromConfigFile(cfg, "cluster");
		stageOptions().features.loadFromConfigFile(cfg, "features");
		std::printf("stage options: %s\n", ini.c_str());
		scans()["real"] = prepare(
		    readScan("../shared/data/mrpt/rot_scan_velodyne.rawlog", 0));
		if (const char* dir = std::getenv("FOREST_SLAM_BENCH_SIM"))
			scans()["forest"] =
			    prepare(readScan(std::string(dir) + "/run.rawlog", 1500));
	}
	catch (const std::exception& e)
	{
		std::fprintf(stderr, "bench_frontend_stages: %s\n", e.what());
		return 1;
	}
	for (const auto& [name, p] : scans())
	{
		const std::string n = name;
		benchmark::RegisterBenchmark(("ground/" + n).c_str(), BM_Ground, n)
		    ->Unit(benchmark::kMillisecond);
		benchmark::RegisterBenchmark(("cluster/" + n).c_str(), BM_Cluster, n)
		    ->Unit(benchmark::kMillisecond);
		benchmark::RegisterBenchmark(("features/" + n).c_str(), BM_Features, n)
		    ->Unit(benchmark::kMillisecond);
	}
	benchmark::RunSpecifiedBenchmarks();
	benchmark::Shutdown();
	return 0;
}
