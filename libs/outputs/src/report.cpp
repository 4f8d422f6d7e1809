#include <forest_slam/core/atomic_file.h>
#include <forest_slam/eval/svg_plot.h>
#include <forest_slam/outputs/report.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

namespace forest_slam::outputs
{
namespace
{
std::string fmt(const char* f, double v)
{
	char b[64];
	std::snprintf(b, sizeof(b), f, v);
	return b;
}

/** The <svg> element of a document written by eval::writeSvgDocument,
 * without the XML declaration (not allowed inside HTML). */
std::string inlineSvg(double w, double h,
                      const std::vector<const eval::SvgPanel*>& panels,
                      const std::string& title)
{
	std::ostringstream os;
	eval::writeSvgDocument(os, w, h, panels, title);
	std::string s = os.str();
	const auto at = s.find("<svg");
	return at == std::string::npos ? s : s.substr(at);
}

const char* qualityName(int q)
{
	switch (q)
	{
		case -1:
			return "no GNSS data";
		case 0:
			return "no fix";
		case 1:
			return "single point";
		case 2:
			return "DGPS";
		case 4:
			return "RTK fixed";
		case 5:
			return "RTK float";
		default:
			return "other";
	}
}
const char* qualityColour(int q)
{
	switch (q)
	{
		case 4:
			return "#2ca02c";
		case 5:
			return "#98df8a";
		case 2:
			return "#1f77b4";
		case 1:
			return "#ff7f0e";
		case 0:
			return "#d62728";
		case -1:
			return "#7f7f7f";
		default:
			return "#9467bd";
	}
}

int qualityAt(const std::vector<GnssEpoch>& g, double t, double max_gap_s)
{
	const auto it = std::lower_bound(g.begin(), g.end(), t,
	                                 [](const GnssEpoch& e, double x)
	                                 { return e.t_s < x; });
	const GnssEpoch* best = nullptr;
	if (it != g.end()) best = &*it;
	if (it != g.begin() && (!best || t - std::prev(it)->t_s < best->t_s - t))
		best = &*std::prev(it);
	if (!best || std::abs(best->t_s - t) > max_gap_s) return -1;
	return best->quality;
}

std::string row(const std::vector<std::string>& cells, bool head = false)
{
	std::string s = "<tr>";
	for (const auto& c : cells)
		s += (head ? "<th>" : "<td>") + eval::svgEscape(c) +
		     (head ? "</th>" : "</td>");
	return s + "</tr>\n";
}
}  // namespace

StandTable standTable(const std::vector<map::TreeRecord>& trees, double area_m2,
                      double class_width_m)
{
	StandTable s;
	s.area_ha = area_m2 / 1e4;
	s.stems = trees.size();
	double sum = 0, sum2 = 0, ba = 0, max_dbh = 0;
	for (const auto& t : trees)
	{
		sum += t.dbh_m;
		sum2 += t.dbh_m * t.dbh_m;
		ba += M_PI / 4 * t.dbh_m * t.dbh_m;
		max_dbh = std::max(max_dbh, t.dbh_m);
	}
	const double per_ha = s.area_ha > 0 ? 1.0 / s.area_ha : 0.0;
	s.stems_per_ha = s.stems * per_ha;
	s.basal_area_m2_per_ha = ba * per_ha;
	if (s.stems > 0)
	{
		s.mean_dbh_m = sum / s.stems;
		s.quadratic_mean_dbh_m = std::sqrt(sum2 / s.stems);
	}
	const int n =
	    trees.empty()
	        ? 0
	        : static_cast<int>(std::floor(max_dbh / class_width_m)) + 1;
	s.classes.resize(n);
	for (int i = 0; i < n; i++)
		s.classes[i].lo_m = i * class_width_m,
		s.classes[i].hi_m = (i + 1) * class_width_m;
	for (const auto& t : trees)
	{
		auto& c = s.classes[std::min(
		    n - 1, static_cast<int>(std::floor(t.dbh_m / class_width_m)))];
		c.stems++;
		c.stems_per_ha += per_ha;
		c.basal_area_m2_per_ha += M_PI / 4 * t.dbh_m * t.dbh_m * per_ha;
	}
	return s;
}

std::vector<std::pair<int, double>> gnssCoverage(
    const core::Trajectory& traj, const std::vector<GnssEpoch>& gnss,
    double max_gap_s)
{
	std::map<int, double> len;
	double total = 0;
	for (size_t i = 1; i < traj.size(); i++)
	{
		const double d =
		    (traj[i].pose.translation() - traj[i - 1].pose.translation())
		        .norm();
		len[qualityAt(gnss, traj[i].t_s, max_gap_s)] += d;
		total += d;
	}
	std::vector<std::pair<int, double>> out;
	for (const auto& [q, l] : len)
		out.emplace_back(q, total > 0 ? l / total : 0);
	return out;
}

void writeReport(const std::string& path, const ReportInputs& in)
{
	static const core::Trajectory kNoTraj;
	static const std::vector<map::TreeRecord> kNoTrees;
	static const std::vector<GnssEpoch> kNoGnss;
	const auto& traj = in.trajectory ? *in.trajectory : kNoTraj;
	const auto& trees = in.trees ? *in.trees : kNoTrees;
	const auto& gnss = in.gnss ? *in.gnss : kNoGnss;

	// Top view: trajectory + trees as circles scaled by DBH (Fig. 12).
	double xmin = 1e300, xmax = -1e300, ymin = 1e300, ymax = -1e300;
	std::vector<Eigen::Vector2d> path_xy;
	for (const auto& p : traj)
	{
		path_xy.push_back(p.pose.translation().head<2>());
		eval::SvgPanel::extend(p.pose.translation().x(),
		                       p.pose.translation().y(), xmin, xmax, ymin,
		                       ymax);
	}
	for (const auto& t : trees)
		eval::SvgPanel::extend(t.x, t.y, xmin, xmax, ymin, ymax);
	if (xmin > xmax) xmin = ymin = -1, xmax = ymax = 1;
	eval::SvgPanel top(0, 0, 640, 600);
	top.setRange(xmin, xmax, ymin, ymax, true);
	const eval::SvgStyle traj_style{"#d62728", 1.5, "none", "", 1.0};
	const eval::SvgStyle tree_style{"#2ca02c", 1.0, "#2ca02c", "", 0.45};
	top.polyline(path_xy, traj_style);
	// Radius on the page: the DBH in metres scaled x5 (stems would be
	// invisible at true size), at least 1.5 px.
	const double px_per_m = std::abs(top.px(1) - top.px(0));
	for (const auto& t : trees)
		top.circle(t.x, t.y, std::max(1.5, 5 * t.dbh_m / 2 * px_per_m),
		           tree_style);
	if (!traj.empty())
		top.cross(traj.front().pose.translation().x(),
		          traj.front().pose.translation().y(), 6,
		          eval::SvgStyle{"#000000", 2.0, "none", "", 1.0});
	top.axes("Top view: trajectory and trees (circle radius = 5 x DBH/2)",
	         "x [m]", "y [m]");
	top.legend({{"trajectory", traj_style},
	            {"tree (size ~ DBH)", tree_style},
	            {"start", eval::SvgStyle{"#000000", 2.0, "none", "", 1.0}}});

	// DBH histogram (5 cm bins).
	const double bin = 0.05;
	double max_dbh = 0;
	for (const auto& t : trees) max_dbh = std::max(max_dbh, t.dbh_m);
	const int nbins =
	    std::max(1, static_cast<int>(std::ceil(max_dbh / bin + 1e-9)));
	std::vector<int> counts(nbins, 0);
	for (const auto& t : trees)
		counts[std::min(nbins - 1, static_cast<int>(t.dbh_m / bin))]++;
	const int cmax =
	    std::max(1, *std::max_element(counts.begin(), counts.end()));
	eval::SvgPanel hist(640, 0, 480, 300);
	hist.setRange(0, nbins * bin * 100, 0, cmax, false);
	const eval::SvgStyle bar{"#1f77b4", 1.0, "#1f77b4", "", 0.8};
	for (int i = 0; i < nbins; i++)
		if (counts[i] > 0)
		{
			const double a = i * bin * 100, b = (i + 1) * bin * 100;
			hist.polyline({{a, 0},
			               {a, double(counts[i])},
			               {b, double(counts[i])},
			               {b, 0},
			               {a, 0}},
			              bar);
		}
	hist.axes("DBH distribution (" + std::to_string(trees.size()) + " trees)",
	          "DBH [cm]", "trees");

	// GNSS coverage along the path.
	eval::SvgPanel cov(640, 300, 480, 300);
	cov.setRange(xmin, xmax, ymin, ymax, true);
	std::vector<std::pair<std::string, eval::SvgStyle>> cov_legend;
	std::map<int, bool> seen;
	for (size_t i = 1; i < traj.size(); i++)
	{
		const int q = qualityAt(gnss, traj[i].t_s, 1.5);
		const eval::SvgStyle s{qualityColour(q), 3.0, "none", "", 1.0};
		cov.line(traj[i - 1].pose.translation().x(),
		         traj[i - 1].pose.translation().y(),
		         traj[i].pose.translation().x(), traj[i].pose.translation().y(),
		         s);
		if (!seen[q])
			cov_legend.emplace_back(qualityName(q), s), seen[q] = true;
	}
	cov.axes("GNSS fix quality along the path", "x [m]", "y [m]");
	cov.legend(cov_legend);

	const auto stand = standTable(trees, in.area_m2);
	const auto coverage = gnssCoverage(traj, gnss);
	double path_m = 0;
	for (size_t i = 1; i < traj.size(); i++)
		path_m += (traj[i].pose.translation() - traj[i - 1].pose.translation())
		              .norm();

	std::ostringstream h;
	h << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
	     "<title>forest-slam report</title>\n<style>body{font-family:sans-"
	     "serif;margin:20px;max-width:1200px}table{border-collapse:collapse;"
	     "margin:8px 0}td,th{border:1px solid #bbb;padding:3px 8px;text-align:"
	     "right}th{background:#eee}h2{margin-top:28px}</style></head><body>\n"
	  << "<h1>forest-slam mapping report</h1>\n<p>" << traj.size()
	  << " lidar poses, path " << fmt("%.1f", path_m) << " m, " << trees.size()
	  << " trees (" << eval::svgEscape(in.trees_source) << "), coordinates: "
	  << eval::svgEscape(in.crs.empty() ? "map frame (not georeferenced)"
	                                    : in.crs)
	  << ".</p>\n"
	  << inlineSvg(1120, 600, {&top, &hist, &cov}, "forest-slam map") << "\n";

	h << "<h2>Stand table</h2>\n<p>Area: mapped ground ("
	  << fmt("%.3f", stand.area_ha)
	  << " ha, cells of dtm.asc with ground points).</p>\n<table>"
	  << row({"stems", "stems/ha", "basal area m²/ha", "mean DBH cm",
	          "quadratic mean DBH cm"},
	         true)
	  << row({std::to_string(stand.stems), fmt("%.1f", stand.stems_per_ha),
	          fmt("%.2f", stand.basal_area_m2_per_ha),
	          fmt("%.1f", stand.mean_dbh_m * 100),
	          fmt("%.1f", stand.quadratic_mean_dbh_m * 100)})
	  << "</table>\n<table>"
	  << row({"DBH class cm", "stems", "stems/ha", "basal area m²/ha"}, true);
	for (const auto& c : stand.classes)
		h << row({fmt("%.0f", c.lo_m * 100) + "–" + fmt("%.0f", c.hi_m * 100),
		          std::to_string(c.stems), fmt("%.1f", c.stems_per_ha),
		          fmt("%.2f", c.basal_area_m2_per_ha)});
	h << "</table>\n<h2>GNSS coverage</h2>\n<table>"
	  << row({"fix quality", "share of path"}, true);
	for (const auto& [q, f] : coverage)
		h << row({qualityName(q), fmt("%.1f %%", 100 * f)});
	h << "</table>\n<p>" << gnss.size()
	  << " GNSS epochs with a GGA message.</p>\n";

	h << "<h2>Loop closures</h2>\n<p>"
	  << (in.loop_closures < 0
	          ? std::string("No loop-closure stage ran in this build: 0 "
	                        "closures applied.")
	          : std::to_string(in.loop_closures) + " loop closures applied.")
	  << "</p>\n";

	const double sps = in.wall_seconds > 0 ? in.scans / in.wall_seconds : 0;
	const double rtf =
	    in.wall_seconds > 0 ? in.data_seconds / in.wall_seconds : 0;
	h << "<h2>Processing</h2>\n<table>"
	  << row({"scans", "data s", "wall s", "scans/s", "real-time factor",
	          "peak memory MB", "output collectors ms/scan", "keyframes",
	          "dense map points"},
	         true)
	  << row({std::to_string(in.scans), fmt("%.1f", in.data_seconds),
	          fmt("%.1f", in.wall_seconds), fmt("%.1f", sps), fmt("%.2f", rtf),
	          fmt("%.0f", in.peak_memory_mb),
	          fmt("%.2f", in.collect_ms_per_scan), std::to_string(in.keyframes),
	          std::to_string(in.dense_points)})
	  << "</table>\n";

	if (!in.files.empty())
	{
		h << "<h2>Files</h2>\n<table>" << row({"file", "what"}, true);
		for (const auto& [f, what] : in.files) h << row({f, what});
		h << "</table>\n";
	}
	h << "</body></html>\n";
	core::writeFileAtomically(path, [&](std::ostream& os) { os << h.str(); });
}

}  // namespace forest_slam::outputs
