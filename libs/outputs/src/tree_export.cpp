#include <forest_slam/core/atomic_file.h>
#include <forest_slam/eval/json_writer.h>
#include <forest_slam/outputs/tree_export.h>
#include <forest_slam/trees/tree_csv.h>

#include <nanoflann.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace forest_slam::outputs
{
namespace
{
struct PathAdaptor
{
	const std::vector<Eigen::Vector2d>& p;
	size_t kdtree_get_point_count() const { return p.size(); }
	double kdtree_get_pt(size_t i, size_t d) const { return p[i][int(d)]; }
	template <class B>
	bool kdtree_get_bbox(B&) const
	{
		return false;
	}
};
using PathTree = nanoflann::KDTreeSingleIndexAdaptor<
    nanoflann::L2_Simple_Adaptor<double, PathAdaptor>, PathAdaptor, 2, size_t>;

double distanceToSegment(const Eigen::Vector2d& q, const Eigen::Vector2d& a,
                         const Eigen::Vector2d& b)
{
	const Eigen::Vector2d ab = b - a;
	const double l2 = ab.squaredNorm();
	const double s = l2 > 0 ? std::clamp((q - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
	return (q - (a + s * ab)).norm();
}
}  // namespace

void setPathDistances(std::vector<map::TreeRecord>& trees,
                      const core::Trajectory& trajectory)
{
	if (trajectory.empty()) return;
	std::vector<Eigen::Vector2d> p;
	p.reserve(trajectory.size());
	for (const auto& s : trajectory)
		p.push_back(s.pose.translation().head<2>());
	double longest = 0;  // segment
	for (size_t i = 1; i < p.size(); i++)
		longest = std::max(longest, (p[i] - p[i - 1]).norm());
	const PathAdaptor ad{p};
	PathTree tree(2, ad, nanoflann::KDTreeSingleIndexAdaptorParams(10));
	tree.buildIndex();
	std::vector<std::pair<size_t, double>> near;
	for (auto& t : trees)
	{
		const double q[2] = {t.x, t.y};
		size_t nearest = 0;
		double d2 = 0;
		tree.knnSearch(q, 1, &nearest, &d2);
		// The nearest point of the polyline lies on a segment one of whose
		// ends is within half the longest segment of it: every such end is
		// within that of the nearest position's distance.
		const double reach = std::sqrt(d2) + 0.5 * longest + 1e-9;
		tree.radiusSearch(q, reach * reach, near, nanoflann::SearchParams());
		const Eigen::Vector2d xy(t.x, t.y);
		double best = std::sqrt(d2);
		for (const auto& [i, unused] : near)
		{
			if (i > 0)
				best = std::min(best, distanceToSegment(xy, p[i - 1], p[i]));
			if (i + 1 < p.size())
				best = std::min(best, distanceToSegment(xy, p[i], p[i + 1]));
		}
		t.path_distance_m = best;
	}
}

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
			    if (std::isfinite(t.path_distance_m))
				    j.kv("path_distance_m", t.path_distance_m);
			    j.endObject().endObject();
		    }
		    j.endArray().endObject();
		    os << "\n";
	    });
}

}  // namespace forest_slam::outputs
