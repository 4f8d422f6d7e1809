#include "text_cells.h"

#include <forest_slam/eval/json_writer.h>
#include <forest_slam/eval/svg_plot.h>
#include <forest_slam/eval/tree_report.h>

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <limits>

namespace forest_slam::eval
{
namespace
{
using detail::cell;
using detail::fmt;

std::string avgStd(const SummaryStats& s)
{
	if (!s.count) return "-";
	return fmt("%.2f/%.2f", 100 * s.mean, 100 * s.std);
}

std::string minMax(const SummaryStats& s)
{
	if (!s.count) return "-";
	return fmt("%.2f/%.2f", 100 * s.min, 100 * s.max);
}

void writeDbhStats(JsonWriter& j, const SummaryStats& s)
{
	j.beginObject()
	    .kv("count", s.count)
	    .kv("avg_m", s.mean)
	    .kv("std_m", s.std)
	    .kv("min_m", s.min)
	    .kv("max_m", s.max)
	    .endObject();
}

void writeDbhErrors(JsonWriter& j, const DbhErrors& e)
{
	j.beginObject()
	    .kv("count", e.count)
	    .kv("rmse_m", e.rmse_m)
	    .kv("mae_m", e.mae_m)
	    .kv("mape_pct", e.mape_pct)
	    .kv("bias_m", e.bias_m)
	    .kv("rel_rmse_pct", e.rel_rmse_pct)
	    .kv("rel_bias_pct", e.rel_bias_pct)
	    .endObject();
}

void writeBound(JsonWriter& j, const char* name, double v)
{
	// An open bound of the default region "all" is null, not +-inf.
	j.kv(name, v);
}
}  // namespace

void printTreeReport(std::ostream& os, const TreeEvalInputs& in,
                     const TreeEvalOptions& opts, const TreeEvaluation& ev)
{
	os << "forest-eval trees\n";
	os << "  ground truth  " << in.gt_path << " (" << in.gt.size()
	   << " trees)\n";
	os << "  estimate      " << in.est_path << " (" << in.est.size()
	   << " trees)\n";
	os << fmt(
	    "  rules         match gate %.3f m, GT DBH >= %.3f m, saplings "
	    "excluded",
	    opts.max_match_m, opts.min_dbh_m);
	if (opts.max_range_m > 0 && !in.traj.empty())
		os << fmt(", within %.2f m of %s", opts.max_range_m,
		          in.traj_path.c_str());
	os << "\n";
	os << fmt(
	    "  GT trees      %zu evaluated; excluded: %zu below min DBH, %zu "
	    "saplings, %zu out of range\n",
	    ev.gt_evaluated, ev.gt_below_min_dbh, ev.gt_sapling,
	    ev.gt_out_of_range);
	os << fmt(
	    "  estimates     %zu true positives, %zu false positives; ignored: "
	    "%zu matched to excluded GT, %zu unmatched out of range\n",
	    ev.tp, ev.fp, ev.est_matched_excluded, ev.est_out_of_range);

	os << "\nDetection: recall " << cell(100 * ev.recall, 0, 1) << " % ("
	   << ev.tp << "/" << ev.tp + ev.fn << "), precision "
	   << cell(100 * ev.precision, 0, 1) << " % (" << ev.tp << "/"
	   << ev.tp + ev.fp << "), F1 " << cell(100 * ev.f1, 0, 1) << " %\n";
	os << "Position (horizontal, TPs): RMSE "
	   << cell(ev.position_err_m.rmse, 0, 3) << " m, mean "
	   << cell(ev.position_err_m.mean, 0, 3) << " m, max "
	   << cell(ev.position_err_m.max, 0, 3) << " m\n";
	const auto& ps = ev.position_structure;
	if (ps.count >= 3)
		os << "  systematic part: mean offset (" << cell(ps.offset_x_m, 0, 3)
		   << ", " << cell(ps.offset_y_m, 0, 3) << ") m, RMSE without it "
		   << cell(ps.rmse_after_offset_m, 0, 3)
		   << " m; a 2D similarity (map scale "
		   << cell((ps.scale - 1) * 100, 0, 3) << " %, rotation "
		   << cell(ps.rotation_deg, 0, 3) << " deg) leaves "
		   << cell(ps.rmse_after_similarity_m, 0, 3) << " m\n";
	os << "DBH (TPs): RMSE " << cell(100 * ev.dbh.rmse_m, 0, 2) << " cm, MAE "
	   << cell(100 * ev.dbh.mae_m, 0, 2) << " cm, MAPE "
	   << cell(ev.dbh.mape_pct, 0, 2) << " %, bias "
	   << cell(100 * ev.dbh.bias_m, 0, 2) << " cm (relative RMSE "
	   << cell(ev.dbh.rel_rmse_pct, 0, 2) << " %, relative bias "
	   << cell(ev.dbh.rel_bias_pct, 0, 2) << " %)\n";

	os << "\nPer region (paper Tables 3-4; DBH in cm)\n";
	os << fmt("  %-12s %-10s %7s %15s %15s %8s %8s %8s %8s %8s\n", "region",
	          "source", "# trees", "avg/std", "min/max", "RMSE", "MAE",
	          "MAPE(%)", "recall%", "precis%");
	for (const auto& rs : ev.regions)
	{
		os << fmt("  %-12s %-10s %7zu %15s %15s\n", rs.region.name.c_str(),
		          "measured", rs.measured_count,
		          avgStd(rs.measured_dbh_m).c_str(),
		          minMax(rs.measured_dbh_m).c_str());
		os << fmt("  %-12s %-10s %7zu %15s %15s", "", "estimated",
		          rs.estimated_count, avgStd(rs.estimated_dbh_m).c_str(),
		          minMax(rs.estimated_dbh_m).c_str())
		   << cell(100 * rs.dbh.rmse_m, 9, 2) << cell(100 * rs.dbh.mae_m, 9, 2)
		   << cell(rs.dbh.mape_pct, 9, 2) << cell(100 * rs.recall, 9, 1)
		   << cell(100 * rs.precision, 9, 1) << "\n";
	}
}

void writeTreeJson(std::ostream& os, const TreeEvalInputs& in,
                   const TreeEvalOptions& opts, const TreeEvaluation& ev)
{
	const bool use_range = opts.max_range_m > 0 && !in.traj.empty();
	JsonWriter j(os);
	j.beginObject();
	j.kv("command", "trees");
	j.key("inputs").beginObject();
	j.kv("gt", in.gt_path).kv("gt_trees", in.gt.size());
	j.kv("est", in.est_path).kv("est_trees", in.est.size());
	if (in.traj_path.empty())
		j.key("traj").null();
	else
		j.kv("traj", in.traj_path);
	if (in.regions_path.empty())
		j.key("regions").null();
	else
		j.kv("regions", in.regions_path);
	j.endObject();

	j.key("options").beginObject();
	j.kv("max_match_m", opts.max_match_m).kv("min_dbh_m", opts.min_dbh_m);
	if (use_range)
		j.kv("max_range_m", opts.max_range_m);
	else
		j.key("max_range_m").null();
	j.endObject();

	j.key("gt").beginObject();
	j.kv("total", in.gt.size())
	    .kv("evaluated", ev.gt_evaluated)
	    .kv("below_min_dbh", ev.gt_below_min_dbh)
	    .kv("sapling", ev.gt_sapling)
	    .kv("out_of_range", ev.gt_out_of_range);
	j.endObject();
	j.key("est").beginObject();
	j.kv("total", in.est.size())
	    .kv("true_positives", ev.tp)
	    .kv("false_positives", ev.fp)
	    .kv("matched_excluded", ev.est_matched_excluded)
	    .kv("out_of_range", ev.est_out_of_range);
	j.endObject();

	j.key("detection").beginObject();
	j.kv("tp", ev.tp).kv("fn", ev.fn).kv("fp", ev.fp);
	j.kv("recall", ev.recall).kv("precision", ev.precision).kv("f1", ev.f1);
	j.endObject();

	j.key("position_err_m").beginObject();
	j.kv("count", ev.position_err_m.count)
	    .kv("rmse", ev.position_err_m.rmse)
	    .kv("mean", ev.position_err_m.mean)
	    .kv("max", ev.position_err_m.max);
	const auto& ps = ev.position_structure;
	j.key("structure").beginObject();
	j.kv("offset_x_m", ps.offset_x_m)
	    .kv("offset_y_m", ps.offset_y_m)
	    .kv("rmse_after_offset_m", ps.rmse_after_offset_m)
	    .kv("scale", ps.scale)
	    .kv("rotation_deg", ps.rotation_deg)
	    .kv("rmse_after_similarity_m", ps.rmse_after_similarity_m);
	j.endObject();
	j.endObject();
	j.key("dbh");
	writeDbhErrors(j, ev.dbh);

	j.key("regions").beginArray();
	for (const auto& rs : ev.regions)
	{
		j.beginObject();
		j.kv("name", rs.region.name);
		writeBound(j, "xmin", rs.region.xmin);
		writeBound(j, "ymin", rs.region.ymin);
		writeBound(j, "xmax", rs.region.xmax);
		writeBound(j, "ymax", rs.region.ymax);
		j.key("measured");
		writeDbhStats(j, rs.measured_dbh_m);
		j.key("estimated");
		writeDbhStats(j, rs.estimated_dbh_m);
		j.kv("tp", rs.tp).kv("fn", rs.fn).kv("fp", rs.fp);
		j.kv("recall", rs.recall).kv("precision", rs.precision).kv("f1", rs.f1);
		j.key("dbh");
		writeDbhErrors(j, rs.dbh);
		j.endObject();
	}
	j.endArray();

	// Per-tree outcome so a reader can find which trees were missed.
	j.key("matches").beginArray();
	for (const auto& m : ev.matches)
		j.beginObject()
		    .kv("gt_id", in.gt[m.a].id)
		    .kv("est_id", in.est[m.b].id)
		    .kv("dist_m", m.dist_m)
		    .kv("gt_dbh_m", in.gt[m.a].dbh_m)
		    .kv("est_dbh_m", in.est[m.b].dbh_m)
		    .kv("gt_status", toString(ev.gt_status[m.a]))
		    .endObject();
	j.endArray();
	j.key("missed_gt_ids").beginArray();
	{
		std::vector<bool> matched(in.gt.size(), false);
		for (const auto& m : ev.matches) matched[m.a] = true;
		for (size_t i = 0; i < in.gt.size(); i++)
			if (ev.gt_status[i] == GtTreeStatus::Evaluated && !matched[i])
				j.value(in.gt[i].id);
	}
	j.endArray();
	j.key("false_positive_est_ids").beginArray();
	for (size_t k = 0; k < in.est.size(); k++)
		if (ev.est_status[k] == EstTreeStatus::FalsePositive)
			j.value(in.est[k].id);
	j.endArray();
	j.endObject();
}

void writeTreeSvg(std::ostream& os, const TreeEvalInputs& in,
                  const TreeEvalOptions& opts, const TreeEvaluation& ev)
{
	(void)opts;
	const double inf = std::numeric_limits<double>::infinity();
	SvgPanel map(0, 0, 700, 650), dbh(700, 0, 600, 650);
	const SvgStyle traj_style{"#7f7f7f", 1.0, "none", "", 1.0};
	const SvgStyle gt_eval{"#000000", 1.2, "none", "", 1.0};
	const SvgStyle gt_excl{"#bbbbbb", 1.0, "none", "", 1.0};
	const SvgStyle fn_style{"#ff7f0e", 2.0, "none", "", 1.0};
	const SvgStyle tp_style{"#2ca02c", 1.2, "#2ca02c", "", 1.0};
	const SvgStyle fp_style{"#d62728", 1.5, "none", "", 1.0};
	const SvgStyle ign_style{"#9467bd", 1.2, "none", "", 1.0};
	const SvgStyle link{"#2ca02c", 1.0, "none", "", 1.0};

	double xmin = inf, xmax = -inf, ymin = inf, ymax = -inf;
	for (const auto& t : in.gt)
		SvgPanel::extend(t.x, t.y, xmin, xmax, ymin, ymax);
	for (const auto& t : in.est)
		SvgPanel::extend(t.x, t.y, xmin, xmax, ymin, ymax);
	std::vector<Eigen::Vector2d> tr;
	for (const auto& p : in.traj)
	{
		tr.push_back(p.pose.translation().head<2>());
		SvgPanel::extend(tr.back().x(), tr.back().y(), xmin, xmax, ymin, ymax);
	}
	map.setRange(xmin, xmax, ymin, ymax, true);
	map.polyline(tr, traj_style);
	std::vector<bool> gt_matched(in.gt.size(), false);
	for (const auto& m : ev.matches) gt_matched[m.a] = true;
	for (size_t i = 0; i < in.gt.size(); i++)
	{
		const auto& t = in.gt[i];
		if (ev.gt_status[i] != GtTreeStatus::Evaluated)
			map.circle(t.x, t.y, 2.5, gt_excl);
		else
			map.circle(t.x, t.y, gt_matched[i] ? 4 : 5,
			           gt_matched[i] ? gt_eval : fn_style);
	}
	for (const auto& m : ev.true_positives)
		map.line(in.gt[m.a].x, in.gt[m.a].y, in.est[m.b].x, in.est[m.b].y,
		         link);
	for (size_t k = 0; k < in.est.size(); k++)
	{
		const auto& t = in.est[k];
		switch (ev.est_status[k])
		{
			case EstTreeStatus::TruePositive:
				map.circle(t.x, t.y, 1.8, tp_style);
				break;
			case EstTreeStatus::FalsePositive:
				map.cross(t.x, t.y, 4, fp_style);
				break;
			default:
				map.cross(t.x, t.y, 3, ign_style);
				break;
		}
	}
	map.axes("Tree map", "x (m)", "y (m)");
	std::vector<std::pair<std::string, SvgStyle>> leg = {
	    {"GT tree (evaluated)", gt_eval},
	    {"GT tree missed", fn_style},
	    {"GT tree excluded", gt_excl},
	    {"estimate: match", tp_style},
	    {"estimate: false positive", fp_style},
	    {"estimate: ignored", ign_style}};
	if (!tr.empty()) leg.push_back({"trajectory", traj_style});
	map.legend(leg);

	// DBH in cm, estimated against reference, over true positives.
	double lo = inf, hi = -inf;
	for (const auto& m : ev.true_positives)
	{
		lo = std::min({lo, 100 * in.gt[m.a].dbh_m, 100 * in.est[m.b].dbh_m});
		hi = std::max({hi, 100 * in.gt[m.a].dbh_m, 100 * in.est[m.b].dbh_m});
	}
	if (!(lo <= hi)) lo = 0, hi = 100;
	lo = std::max(0.0, lo - 5), hi = hi + 5;
	dbh.setRange(lo, hi, lo, hi, false);
	dbh.line(lo, lo, hi, hi, SvgStyle{"#7f7f7f", 1.0, "none", "5,4", 1.0});
	for (const auto& m : ev.true_positives)
		dbh.circle(100 * in.gt[m.a].dbh_m, 100 * in.est[m.b].dbh_m, 3.5,
		           SvgStyle{"#1f77b4", 1.0, "#1f77b4", "", 0.7});
	dbh.axes(fmt("DBH: RMSE %.2f cm, MAE %.2f cm, MAPE %.2f %%",
	             100 * ev.dbh.rmse_m, 100 * ev.dbh.mae_m, ev.dbh.mape_pct),
	         "reference DBH (cm)", "estimated DBH (cm)");
	dbh.legend({{"1:1", SvgStyle{"#7f7f7f", 1.0, "none", "5,4", 1.0}},
	            {"matched tree", SvgStyle{"#1f77b4", 3.0, "none", "", 1.0}}});
	writeSvgDocument(os, 1300, 650, {&map, &dbh},
	                 "forest-eval trees: " + in.est_path);
}

}  // namespace forest_slam::eval
