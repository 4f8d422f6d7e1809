#include <forest_slam/core/atomic_file.h>
#include <forest_slam/eval/json_writer.h>
#include <forest_slam/outputs/tree_export.h>
#include <forest_slam/trees/tree_csv.h>

#include <cstdio>
#include <fstream>
#include <sstream>

namespace forest_slam::outputs
{
void writeTreesCsvGeo(const std::string& path,
                      const std::vector<map::TreeRecord>& trees,
                      const std::optional<Georeference>& geo)
{
	if (!geo)
	{
		trees::writeTreesCsv(path, trees);
		return;
	}
	// The tree layer's own columns (libs/trees) with the geographic ones
	// appended to each row, so the base columns stay exactly those.
	const std::string base = core::tempPathFor(path) + ".base";
	trees::writeTreesCsv(base, trees);
	std::vector<std::string> lines;
	{
		std::ifstream in(base);
		for (std::string l; std::getline(in, l);) lines.push_back(l);
	}
	std::remove(base.c_str());
	if (lines.size() != trees.size() + 1)
		throw std::runtime_error("'" + path + "': unexpected row count");
	core::writeFileAtomically(
	    path,
	    [&](std::ostream& os)
	    {
		    os << lines[0] << "," << kTreesGeoColumns << "\n";
		    char buf[160];
		    for (size_t i = 0; i < trees.size(); i++)
		    {
			    const Eigen::Vector3d p(trees[i].x, trees[i].y,
			                            trees[i].z_ground);
			    const auto e = geo->toProjected(p);
			    const auto ll = geo->toLatLon(p);
			    std::snprintf(buf, sizeof(buf), ",%.3f,%.3f,%.9f,%.9f", e.x(),
			                  e.y(), ll.lat_deg, ll.lon_deg);
			    os << lines[i + 1] << buf << "\n";
		    }
	    });
}

void writeTreesGeoJson(const std::string& path,
                       const std::vector<map::TreeRecord>& trees,
                       const std::optional<Georeference>& geo)
{
	core::writeFileAtomically(
	    path,
	    [&](std::ostream& os)
	    {
		    eval::JsonWriter j(os);
		    j.beginObject().kv("type", "FeatureCollection");
		    j.kv("name", "trees");
		    if (!geo)
			    j.kv("coordinates_note",
			         "map frame [m] (x, y, z_ground): not georeferenced");
		    j.key("features").beginArray();
		    for (const auto& t : trees)
		    {
			    const Eigen::Vector3d p(t.x, t.y, t.z_ground);
			    j.beginObject().kv("type", "Feature");
			    j.key("geometry").beginObject().kv("type", "Point");
			    j.key("coordinates").beginArray();
			    if (geo)
			    {
				    const auto ll = geo->toLatLon(p);
				    j.value(ll.lon_deg).value(ll.lat_deg).value(ll.alt_m);
			    }
			    else
				    j.value(t.x).value(t.y).value(t.z_ground);
			    j.endArray().endObject();
			    j.key("properties").beginObject();
			    j.kv("id", static_cast<long long>(t.id));
			    j.kv("x", t.x).kv("y", t.y).kv("z_ground", t.z_ground);
			    if (geo)
			    {
				    const auto e = geo->toProjected(p);
				    j.kv("easting_m", e.x()).kv("northing_m", e.y());
			    }
			    j.kv("dbh_m", t.dbh_m).kv("height_m", t.height_m);
			    j.kv("n_points", static_cast<long long>(t.n_points));
			    j.kv("fit_rmse_m", t.fit_rmse_m);
			    j.kv("arc_coverage_deg", t.arc_coverage_deg);
			    j.kv("n_slices", static_cast<long long>(t.n_slices));
			    j.kv("quality", static_cast<long long>(t.quality));
			    j.endObject().endObject();
		    }
		    j.endArray().endObject();
		    os << "\n";
	    });
}

}  // namespace forest_slam::outputs
