#include <forest_slam/core/atomic_file.h>
#include <forest_slam/core/log.h>
#include <forest_slam/core/memory.h>
#include <forest_slam/io/las.h>
#include <forest_slam/io/tum.h>
#include <forest_slam/outputs/classification.h>
#include <forest_slam/outputs/georeference.h>
#include <forest_slam/outputs/octomap_export.h>
#include <forest_slam/outputs/report.h>
#include <forest_slam/outputs/simplemap_export.h>
#include <forest_slam/outputs/tree_export.h>
#include <forest_slam/outputs/write_outputs.h>
#include <forest_slam/trees/stem_detector.h>

#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/serialization/CArchive.h>

#include <chrono>
#include <cstdio>
#include <future>
#include <limits>
#include <map>
#include <memory>

namespace forest_slam::outputs
{
namespace
{
double secondsSince(std::chrono::steady_clock::time_point t0)
{
	return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
	    .count();
}

/** map.ply: binary little endian, double x y z in the output frame. */
void writePlyHeader(std::ostream& os, size_t n)
{
	os << "ply\nformat binary_little_endian 1.0\ncomment forest-slam "
	      "dense map\nelement vertex "
	   << n
	   << "\nproperty double x\nproperty double y\nproperty double z\n"
	      "property ushort intensity\nproperty uchar classification\n"
	      "property double gps_time\nend_header\n";
}
void writePlyPoint(std::ostream& os, const Eigen::Vector3d& xyz,
                   uint16_t intensity, uint8_t cls, double gps_time_s)
{
	os.write(reinterpret_cast<const char*>(xyz.data()), 24);
	os.write(reinterpret_cast<const char*>(&intensity), 2);
	os.write(reinterpret_cast<const char*>(&cls), 1);
	os.write(reinterpret_cast<const char*>(&gps_time_s), 8);
}

/** map.pcd: PCL binary, float x y z (map frame: floats cannot hold UTM
 * coordinates to the millimetre), intensity, label. */
void writePcdHeader(std::ostream& os, size_t n)
{
	os << "# .PCD v0.7 - forest-slam dense map (map frame)\nVERSION "
	      "0.7\nFIELDS x y z intensity label\nSIZE 4 4 4 4 4\nTYPE F F "
	      "F F U\nCOUNT 1 1 1 1 1\nWIDTH "
	   << n << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << n
	   << "\nDATA binary\n";
}
void writePcdPoint(std::ostream& os, const DensePoint& p, uint8_t cls)
{
	const float rec[4] = {p.xyz.x(), p.xyz.y(), p.xyz.z(),
	                      p.intensity / 256.0f};
	const uint32_t label = cls;
	os.write(reinterpret_cast<const char*>(rec), sizeof(rec));
	os.write(reinterpret_cast<const char*>(&label), 4);
}
}  // namespace

std::string describeOutput(const std::string& f)
{
	static const std::map<std::string, std::string> kWhat = {
	    {"trajectory.tum", "lidar pose per scan, TUM (t x y z qx qy qz qw)"},
	    {"trajectory.kitti", "same poses as 3x4 KITTI matrices, one per line"},
	    {"keyframes.simplemap",
	     "MRPT CSimpleMap: keyframe point clouds at their lidar poses"},
	    {"forest.map",
	     "serialized CForestMap (submaps + tree layer), loadable"},
	    {"map.las",
	     "dense map, LAS 1.4 format 6: classes, intensity, GPS time"},
	    {"map.ply", "dense map, binary PLY"},
	    {"map.pcd", "dense map, binary PCD (map frame)"},
	    {"map.bt",
	     "OctoMap OcTree (binary): occupied + free space by ray casting"},
	    {"map.ot", "OctoMap ColorOcTree: occupied voxels coloured by height"},
	    {"trees.csv", "tree list: position, DBH, height, quality per stem"},
	    {"trees.geojson", "trees as GeoJSON points for GIS"},
	    {"dtm.asc", "terrain model, ESRI ASCII grid from the ground points"},
	    {"report.html", "self-contained report: map, DBH, stand table, GNSS"},
	    {"run_summary.json", "counts and timing of the run"},
	};
	const auto it = kWhat.find(f);
	return it == kWhat.end() ? "" : it->second;
}

void writeForestMap(const std::string& path, const map::CForestMap& m)
{
	mrpt::io::CFileGZOutputStream out;
	if (!out.open(core::tempPathFor(path), 1))
		throw std::runtime_error("cannot create '" + path + "'");
	auto arch = mrpt::serialization::archiveFrom(out);
	arch << m;
	out.close();
	core::commitTempFile(path);
}

double peakMemoryMb()
{
	return core::peakRssMb();
}

OutputSummary writeRunOutputs(const OutputInputs& in, const std::string& dir)
{
	const auto t_all = std::chrono::steady_clock::now();
	const auto& o = in.options;
	const auto& col = in.collector;
	const auto geo = Georeference::fromOptions(in.geo);
	OutputSummary sum;
	sum.dense_points = col.dense().size();
	sum.keyframes = col.keyframes().size();
	const auto add =
	    [&](const std::string& name, std::chrono::steady_clock::time_point t0)
	{
		sum.files.push_back({dir + "/" + name, describeOutput(name)});
		// The peak so far tells which output raised the run's peak RSS.
		FS_LOG_INFO("wrote " << name << " in " << secondsSince(t0)
		                     << " s; peak RSS so far " << core::peakRssMb()
		                     << " MB");
	};
	const auto to_output = [&](const Eigen::Vector3d& p)
	{ return geo ? geo->toProjected(p) : p; };

	const KeyframeCloudLoader cloud_of = [&](size_t i)
	{ return col.keyframeCloud(i); };

	auto t = std::chrono::steady_clock::now();
	if (o.trajectory_tum)
	{
		io::writeTum(dir + "/trajectory.tum", in.trajectory);
		add("trajectory.tum", t);
	}
	if (o.trajectory_kitti)
	{
		t = std::chrono::steady_clock::now();
		io::writeKitti(dir + "/trajectory.kitti", in.trajectory);
		add("trajectory.kitti", t);
	}
	// The OctoMap (ray casting, then the tree's updates in keyframe order:
	// the longest writer, 16-19 s of the forest-sim runs with one core
	// busy) is written on its own thread while the writers below go on:
	// they all only read the collector, the map and the trajectory.
	// (The list before the future: if a writer below throws, the future's
	// destructor waits for the thread, which may still fill the list.)
	std::vector<WrittenFile> octomap_files;
	std::future<void> octomap;
	if (o.octomap_bt || o.octomap_ot)
		octomap = std::async(
		    std::launch::async,
		    [&, t0 = std::chrono::steady_clock::now()]
		    {
			    const std::string bt = dir + "/map.bt";
			    const auto s =
			        writeOctomap(col.keyframes(), cloud_of,
			                     o.octomap_resolution_m, o.octomap_max_range_m,
			                     bt, o.octomap_ot ? dir + "/map.ot" : "",
			                     o.octomap_keyframe_spacing_m);
			    FS_LOG_INFO(
			        "OctoMap: "
			        << s.keyframes << " keyframes (" << s.keyframes_skipped
			        << " skipped: within octomap_keyframe_spacing_m"
			           " of one cast), "
			        << s.rays << " rays, " << s.occupied_leaves
			        << " occupied / " << s.free_leaves << " free leaves");
			    const auto listed = [&](const std::string& name)
			    {
				    octomap_files.push_back(
				        {dir + "/" + name, describeOutput(name)});
				    FS_LOG_INFO("wrote "
				                << name << " in " << secondsSince(t0)
				                << " s (beside the other writers); peak RSS "
				                   "so far "
				                << core::peakRssMb() << " MB");
			    };
			    if (o.octomap_bt)
				    listed("map.bt");
			    else
				    std::remove(bt.c_str());
			    if (o.octomap_ot) listed("map.ot");
		    });
	if (o.keyframes_simplemap)
	{
		t = std::chrono::steady_clock::now();
		writeSimpleMap(dir + "/keyframes.simplemap", col.keyframes(), cloud_of);
		add("keyframes.simplemap", t);
	}
	// The OctoMap's files are listed where they were before it had its
	// own thread: after the trajectory and the keyframes.
	const size_t octomap_files_at = sum.files.size();

	// Terrain and trees of the dense map. The dense map may be mostly on
	// disk (spill_to_disk): it is read tile by tile, twice at most (bounds,
	// then classes and the files), never held whole, except to detect
	// trees on it (tree layer empty) or for a DTM without ground lattice.
	const DenseMap& dense = col.dense();
	std::vector<map::TreeRecord> tree_list = in.map.trees();
	std::string trees_source = "tree layer of the map";
	trees::TerrainModel terrain;
	if (dense.size() > 0)
	{
		t = std::chrono::steady_clock::now();
		terrain = terrainForCloud(dense, col.groundLattice(), in.tree_options);
		if (tree_list.empty() && o.detect_trees_if_empty &&
		    (o.trees_csv || o.trees_geojson || o.report_html || o.forest_map ||
		     o.las))
		{
			std::vector<Eigen::Vector3d> xyz;
			xyz.reserve(dense.size());
			dense.forEachTile(
			    [&](const std::vector<DensePoint>& pts)
			    {
				    for (const auto& p : pts)
					    xyz.push_back(p.xyz.cast<double>());
			    });
			tree_list = trees::toRecords(
			    trees::detectTrees(xyz, terrain, in.tree_options));
			trees_source = "detected on the dense map at the end of the run";
			sum.trees_detected_here = true;
			FS_LOG_INFO("trees: tree layer empty, "
			            << tree_list.size() << " stems detected on the "
			            << dense.size() << "-point dense map in "
			            << secondsSince(t) << " s");
		}
	}
	sum.trees = tree_list.size();
	// How far each stem is from the path: stems seen from afar are less
	// accurate (doc/trees.md, "Trees beyond 15 m of the path"), so users
	// can cut the list at their plot's radius.
	setPathDistances(tree_list, in.trajectory);

	if (o.forest_map)
	{
		t = std::chrono::steady_clock::now();
		const std::string path = dir + "/forest.map";
		if (sum.trees_detected_here)
		{
			map::CForestMap with_trees = in.map;
			with_trees.setTrees(tree_list);
			writeForestMap(path, with_trees);
		}
		else
			writeForestMap(path, in.map);
		add("forest.map", t);
	}

	// One pass over the tiles: class of every point, DTM cells, and the
	// dense-map files point by point.
	GroundGridBuilder dtm_cells(o.dtm_cell_m);
	if (dense.size() > 0)
	{
		t = std::chrono::steady_clock::now();
		std::unique_ptr<io::LasStreamWriter> las;
		std::unique_ptr<core::AtomicFileWriter> ply, pcd;
		if (o.las)
		{
			// The LAS offset is the minimum of the output coordinates.
			Eigen::Vector3d lo =
			    Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
			dense.forEachTile(
			    [&](const std::vector<DensePoint>& pts)
			    {
				    for (const auto& p : pts)
					    lo = lo.cwiseMin(to_output(p.xyz.cast<double>()));
			    });
			io::LasWriteOptions lo_opts;
			if (geo) lo_opts.wkt = geo->wkt();
			las = std::make_unique<io::LasStreamWriter>(
			    dir + "/map.las", dense.size(),
			    io::LasStreamWriter::offsetFor(lo), lo_opts);
		}
		if (o.ply)
		{
			ply = std::make_unique<core::AtomicFileWriter>(dir + "/map.ply",
			                                               true);
			writePlyHeader(ply->stream(), dense.size());
		}
		if (o.pcd)
		{
			pcd = std::make_unique<core::AtomicFileWriter>(dir + "/map.pcd",
			                                               true);
			writePcdHeader(pcd->stream(), dense.size());
		}
		const PointClassifier classifier(terrain, tree_list, o);
		const double t0 = dense.timeOrigin();
		dense.forEachTile(
		    [&](const std::vector<DensePoint>& pts)
		    {
			    for (const auto& p : pts)
			    {
				    const Eigen::Vector3d m = p.xyz.cast<double>();
				    const uint8_t c = classifier.classify(m);
				    if (!las && !ply && !pcd && c != kGround) continue;
				    const Eigen::Vector3d out = to_output(m);
				    if (c == kGround) dtm_cells.add(out);
				    const double gps = io::unixToAdjustedGpsTime(t0 + p.t_s);
				    if (las)
					    las->add(out, p.intensity, c, p.scan_angle * 0.006f,
					             gps);
				    if (ply)
					    writePlyPoint(ply->stream(), out, p.intensity, c, gps);
				    if (pcd) writePcdPoint(pcd->stream(), p, c);
			    }
		    });
		if (las)
		{
			las->commit();
			add("map.las", t);
		}
		if (ply)
		{
			ply->commit();
			add("map.ply", t);
		}
		if (pcd)
		{
			pcd->commit();
			add("map.pcd", t);
		}
	}
	if (octomap.valid())
	{
		octomap.get();  // rethrows its error
		sum.files.insert(sum.files.begin() + octomap_files_at,
		                 octomap_files.begin(), octomap_files.end());
	}
	const ElevationGrid dtm = dtm_cells.grid();
	if (o.trees_csv)
	{
		t = std::chrono::steady_clock::now();
		writeTreesCsvGeo(dir + "/trees.csv", tree_list, geo);
		add("trees.csv", t);
	}
	if (o.trees_geojson)
	{
		t = std::chrono::steady_clock::now();
		writeTreesGeoJson(dir + "/trees.geojson", tree_list, geo);
		add("trees.geojson", t);
	}
	if (o.dtm_asc)
	{
		if (dtm.cellsWithData() > 0)
		{
			t = std::chrono::steady_clock::now();
			writeEsriAscii(dir + "/dtm.asc", dtm);
			add("dtm.asc", t);
		}
		else
			FS_LOG_WARN(
			    "dtm.asc not written: no ground point in the dense map");
	}
	if (o.report_html)
	{
		t = std::chrono::steady_clock::now();
		ReportInputs r;
		r.trajectory = &in.trajectory;
		r.trees = &tree_list;
		r.gnss = &col.gnss();
		r.trees_source = trees_source;
		r.area_m2 = dtm.cellsWithData() * dtm.cell_m * dtm.cell_m;
		r.crs = geo ? geo->crsName() : "";
		r.scans = in.figures.scans;
		r.data_seconds = in.figures.data_seconds;
		r.wall_seconds = in.figures.wall_seconds;
		r.peak_memory_mb = peakMemoryMb();
		r.collect_ms_per_scan =
		    col.scans() > 0 ? 1e3 * col.collectSeconds() / col.scans() : 0;
		r.keyframes = sum.keyframes;
		r.dense_points = sum.dense_points;
		r.loop_closures = in.figures.loop_closures;
		for (const auto& f : sum.files)
			r.files.emplace_back(f.path.substr(dir.size() + 1), f.what);
		r.files.emplace_back("report.html", describeOutput("report.html"));
		writeReport(dir + "/report.html", r);
		add("report.html", t);
	}
	sum.seconds = secondsSince(t_all);
	return sum;
}

}  // namespace forest_slam::outputs
