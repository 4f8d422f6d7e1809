// Front-end stage timings on a real VLP-16 scan (MRPT sample rawlog):
// ground lattice labelling and hierarchical k-means of the non-ground points.
// Usage: bench_frontend [RAWLOG] [REPETITIONS]
#include <forest_slam/cluster/hierarchical_kmeans.h>
#include <forest_slam/core/scan_points.h>
#include <forest_slam/ground/ground_lattice.h>
#include <forest_slam/io/rawlog_reader.h>
#include <mrpt/obs/CObservationRotatingScan.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>

using namespace forest_slam;

int main(int argc, char** argv)
{
	const std::string path = argc > 1 ? argv[1] : "../shared/data/mrpt/rot_scan_velodyne.rawlog";
	const int reps = argc > 2 ? std::stoi(argv[2]) : 200;
	try
	{
		io::RawlogReader r(path);
		mrpt::obs::CObservationRotatingScan::Ptr scan;
		while (auto o = r.next())
			if ((scan = std::dynamic_pointer_cast<mrpt::obs::CObservationRotatingScan>(o))) break;
		if (!scan) throw std::runtime_error("no CObservationRotatingScan in " + path);
		if (scan->lidarModel == "UNKNOWN_SCANNER" || scan->lidarModel.empty())
			scan->lidarModel = "VLP16";
		const auto sp = core::unpackRotatingScan(*scan);
		std::vector<Eigen::Vector3f> pts;
		for (const auto& p : sp.points) pts.emplace_back(p.x, p.y, p.z);

		std::vector<double> t_ground, t_cluster;
		size_t n_ground = 0, n_clusters = 0, n_nonground = 0;
		ground::GroundLattice lattice;
		for (int k = 0; k < reps; k++)
		{
			auto t0 = std::chrono::steady_clock::now();
			const auto lab = lattice.labelScan(pts, Eigen::Vector3d::Zero());
			auto t1 = std::chrono::steady_clock::now();
			std::vector<Eigen::Vector3f> ng;
			for (size_t i = 0; i < pts.size(); i++)
				if (!lab[i]) ng.push_back(pts[i]);
			auto t2 = std::chrono::steady_clock::now();
			const auto cl = cluster::hierarchicalKMeans(ng);
			auto t3 = std::chrono::steady_clock::now();
			t_ground.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
			t_cluster.push_back(std::chrono::duration<double, std::milli>(t3 - t2).count());
			n_ground = std::count(lab.begin(), lab.end(), 1);
			n_nonground = ng.size();
			n_clusters = cl.clusterCount();
		}
		auto stat = [](std::vector<double> v, const char* name) {
			std::sort(v.begin(), v.end());
			std::printf("%-10s median %7.3f ms  p95 %7.3f ms  max %7.3f ms\n", name,
						v[v.size() / 2], v[v.size() * 95 / 100], v.back());
		};
		std::printf("scan: %zu points (%s), %zu ground, %zu non-ground in %zu clusters, %d reps\n",
					pts.size(), scan->lidarModel.c_str(), n_ground, n_nonground, n_clusters, reps);
		stat(t_ground, "ground");
		stat(t_cluster, "cluster");
	}
	catch (const std::exception& e)
	{
		std::fprintf(stderr, "bench_frontend: %s\n", e.what());
		return 1;
	}
	return 0;
}
