#include "text_cells.h"

#include <forest_slam/eval/json_writer.h>
#include <forest_slam/eval/svg_plot.h>
#include <forest_slam/eval/traj_report.h>

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

void writeStats(JsonWriter& j, const SummaryStats& s)
{
	j.beginObject()
	    .kv("count", s.count)
	    .kv("mean", s.mean)
	    .kv("std", s.std)
	    .kv("min", s.min)
	    .kv("max", s.max)
	    .kv("median", s.median)
	    .kv("rmse", s.rmse)
	    .endObject();
}

void writePose(JsonWriter& j, const Eigen::Isometry3d& T)
{
	const Eigen::Vector3d rpy = rollPitchYawDeg(T.linear());
	j.beginObject()
	    .kv("x_m", T.translation().x())
	    .kv("y_m", T.translation().y())
	    .kv("z_m", T.translation().z())
	    .kv("roll_deg", rpy.x())
	    .kv("pitch_deg", rpy.y())
	    .kv("yaw_deg", rpy.z())
	    .endObject();
}

void writeClosure(JsonWriter& j, const ReturnToStartError& c)
{
	j.beginObject()
	    .kv("t_first_s", c.t_first_s)
	    .kv("t_last_s", c.t_last_s)
	    .kv("roll_deg", c.roll_deg)
	    .kv("pitch_deg", c.pitch_deg)
	    .kv("yaw_deg", c.yaw_deg)
	    .kv("total_rot_deg", c.total_rot_deg)
	    .kv("angle_deg", c.angle_deg)
	    .kv("x_m", c.x_m)
	    .kv("y_m", c.y_m)
	    .kv("z_m", c.z_m)
	    .kv("total_trans_m", c.total_trans_m)
	    .endObject();
}

std::string closureRow(const std::string& label, const ReturnToStartError& c)
{
	return fmt("  %-14s", label.c_str()) + cell(c.roll_deg, 8, 2) +
	       cell(c.pitch_deg, 8, 2) + cell(c.yaw_deg, 8, 2) +
	       cell(c.total_rot_deg, 11, 2) + cell(c.angle_deg, 8, 2) +
	       cell(c.x_m, 9, 3) + cell(c.y_m, 9, 3) + cell(c.z_m, 9, 3) +
	       cell(c.total_trans_m, 12, 3) + "\n";
}

std::string statsRow(const std::string& label, const SummaryStats& s,
                     int decimals)
{
	return fmt("  %-18s%6zu", label.c_str(), s.count) +
	       cell(s.mean, 10, decimals) + cell(s.std, 10, decimals) +
	       cell(s.min, 10, decimals) + cell(s.max, 10, decimals) +
	       cell(s.rmse, 10, decimals) + "\n";
}

std::string span(const core::Trajectory& t)
{
	if (t.empty()) return "empty";
	return fmt("%zu poses, %.3f .. %.3f s", t.size(), t.front().t_s,
	           t.back().t_s);
}
}  // namespace

TrajReport evaluateTrajectory(const TrajEvalInputs& in,
                              const TrajEvalOptions& opts)
{
	if (in.est.empty())
		throw std::runtime_error("estimated trajectory '" + in.est_path +
		                         "' has no poses");
	TrajReport r;
	r.options = opts;
	r.est_poses = in.est.size();
	r.gt_poses = in.gt.size();
	r.return_to_start = returnToStartError(in.est);
	if (!in.gt_path.empty() || !in.gt.empty())
	{
		if (in.gt.empty())
			throw std::runtime_error("ground-truth trajectory '" + in.gt_path +
			                         "' has no poses");
		r.has_gt = true;
		r.association =
		    associateByInterpolation(in.gt, in.est, opts.association);
		const auto& pairs = r.association.pairs;
		r.gt_path_length_m = gtDistanceTravelled(pairs).back();
		r.ate_unaligned = absoluteTrajectoryError(pairs, false);
		r.ate_aligned = absoluteTrajectoryError(pairs, true);
		r.rpe = relativePoseError(pairs, opts.rpe);
		r.vertical = verticalDrift(pairs);
		// The GT's own closure over the estimate's span, when the GT covers
		// both ends (otherwise the comparison would mix different spans).
		Eigen::Isometry3d g0, g1;
		if (core::interpolatePose(in.gt, in.est.front().t_s, g0) &&
		    core::interpolatePose(in.gt, in.est.back().t_s, g1))
		{
			r.gt_return_to_start =
			    returnToStartError(core::StampedPose{in.est.front().t_s, g0},
			                       core::StampedPose{in.est.back().t_s, g1});
			r.return_to_start_vs_gt =
			    returnToStartErrorVsGt(in.est.front(), in.est.back(), g0, g1);
		}
	}
	if (in.gnss) r.gnss = gnssDrift(in.est, *in.gnss, opts.gnss);
	return r;
}

void printTrajReport(std::ostream& os, const TrajEvalInputs& in,
                     const TrajReport& r)
{
	os << "forest-eval traj\n";
	os << "  estimate      " << in.est_path << " (" << span(in.est) << ")\n";
	if (r.has_gt)
		os << "  ground truth  " << in.gt_path << " (" << span(in.gt) << ")\n";
	if (in.gnss)
		os << "  GNSS          " << in.gnss_path << " (" << in.gnss->size()
		   << " fixes)\n";
	if (r.has_gt)
	{
		const auto& a = r.association;
		os << fmt(
		    "  associated    %zu estimate poses (%zu outside the GT time "
		    "span, %zu in GT gaps > %.2f s); GT path %.2f m\n",
		    a.pairs.size(), a.est_outside_gt, a.est_in_gt_gap,
		    r.options.association.max_gt_gap_s, r.gt_path_length_m);

		os << "\nATE                         N      mean       std       min   "
		      "    "
		      "max      RMSE\n";
		os << statsRow("unaligned (m)", r.ate_unaligned.trans_m, 4);
		os << statsRow("SE(3) aligned (m)", r.ate_aligned.trans_m, 4);
		os << statsRow("unaligned (deg)", r.ate_unaligned.rot_deg, 3);
		os << statsRow("aligned (deg)", r.ate_aligned.rot_deg, 3);

		os << "\nRPE (KITTI style, by GT distance travelled)\n";
		os << "  length (m)  segments   trans (%)   rot (deg/m)\n";
		for (const auto& l : r.rpe.per_length)
			os << fmt("  %10.1f  %8zu", l.length_m, l.segments) +
			          cell(l.trans_err_pct, 12, 3) +
			          cell(l.rot_err_deg_per_m, 14, 5) + "\n";
		os << fmt("  %10s  %8zu", "all", r.rpe.segments) +
		          cell(r.rpe.trans_err_pct, 12, 3) +
		          cell(r.rpe.rot_err_deg_per_m, 14, 5) + "\n";

		os << "\nVertical drift over " << cell(r.vertical.distance_m, 0, 2)
		   << " m: end |dz| " << cell(r.vertical.end_abs_err_m, 0, 3) << " m ("
		   << cell(r.vertical.end_pct, 0, 3) << " %), max |dz| "
		   << cell(r.vertical.max_abs_err_m, 0, 3) << " m ("
		   << cell(r.vertical.max_pct, 0, 3) << " %)\n";
	}

	os << "\nReturn to start (paper Table 5; last vs first estimated pose)\n";
	os << "                    roll   pitch     yaw  total rot   angle        x"
	      "        y        z  total trans\n";
	os << "                   (deg)   (deg)   (deg)      (deg)   (deg)      (m)"
	      "      (m)      (m)          (m)\n";
	os << closureRow("estimate", r.return_to_start);
	if (r.gt_return_to_start)
		os << closureRow("ground truth", *r.gt_return_to_start);
	if (r.return_to_start_vs_gt)
		os << closureRow("est. vs GT", *r.return_to_start_vs_gt);

	if (r.gnss)
	{
		const auto& g = *r.gnss;
		os << fmt(
		    "\nDrift against GNSS every %.1f s (paper Table 6): %zu samples, "
		    "%zu skipped (no fix within %.2f s)\n",
		    r.options.gnss.interval_s, g.samples.size(), g.skipped_no_fix,
		    r.options.gnss.max_fix_offset_s);
		os << "                         N      mean       std       min       "
		      "max"
		      "      RMSE\n";
		os << statsRow("3D (m)", g.dist_3d_m, 3);
		os << statsRow("horizontal (m)", g.dist_2d_m, 3);
		os << statsRow("3D SE(3)-aligned", g.aligned_dist_3d_m, 3);
	}
}

void writeTrajJson(std::ostream& os, const TrajEvalInputs& in,
                   const TrajReport& r)
{
	JsonWriter j(os);
	j.beginObject();
	j.kv("command", "traj");
	j.key("inputs").beginObject();
	j.kv("est", in.est_path).kv("est_poses", r.est_poses);
	if (r.has_gt)
		j.kv("gt", in.gt_path).kv("gt_poses", r.gt_poses);
	else
		j.key("gt").null().key("gt_poses").null();
	if (in.gnss)
		j.kv("gnss", in.gnss_path).kv("gnss_fixes", in.gnss->size());
	else
		j.key("gnss").null().key("gnss_fixes").null();
	j.endObject();

	j.key("options").beginObject();
	j.kv("max_gt_gap_s", r.options.association.max_gt_gap_s);
	j.key("rpe_lengths_m").beginArray();
	for (double l : r.options.rpe.lengths_m) j.value(l);
	j.endArray();
	j.kv("gnss_interval_s", r.options.gnss.interval_s);
	j.kv("gnss_max_fix_offset_s", r.options.gnss.max_fix_offset_s);
	j.endObject();

	if (r.has_gt)
	{
		const auto& a = r.association;
		j.key("association").beginObject();
		j.kv("pairs", a.pairs.size())
		    .kv("est_outside_gt", a.est_outside_gt)
		    .kv("est_in_gt_gap", a.est_in_gt_gap)
		    .kv("t_first_s", a.pairs.front().t_s)
		    .kv("t_last_s", a.pairs.back().t_s)
		    .kv("gt_path_length_m", r.gt_path_length_m);
		j.endObject();

		j.key("ate").beginObject();
		j.key("unaligned").beginObject();
		j.key("trans_m");
		writeStats(j, r.ate_unaligned.trans_m);
		j.key("rot_deg");
		writeStats(j, r.ate_unaligned.rot_deg);
		j.endObject();
		j.key("aligned_se3").beginObject();
		j.key("trans_m");
		writeStats(j, r.ate_aligned.trans_m);
		j.key("rot_deg");
		writeStats(j, r.ate_aligned.rot_deg);
		j.key("alignment");
		writePose(j, r.ate_aligned.alignment);
		j.endObject();
		j.endObject();

		j.key("rpe").beginObject();
		j.kv("segments", r.rpe.segments)
		    .kv("trans_err_pct", r.rpe.trans_err_pct)
		    .kv("rot_err_deg_per_m", r.rpe.rot_err_deg_per_m);
		j.key("per_length").beginArray();
		for (const auto& l : r.rpe.per_length)
			j.beginObject()
			    .kv("length_m", l.length_m)
			    .kv("segments", l.segments)
			    .kv("trans_err_pct", l.trans_err_pct)
			    .kv("rot_err_deg_per_m", l.rot_err_deg_per_m)
			    .endObject();
		j.endArray();
		j.endObject();

		j.key("vertical_drift").beginObject();
		j.kv("distance_m", r.vertical.distance_m)
		    .kv("end_abs_err_m", r.vertical.end_abs_err_m)
		    .kv("end_pct", r.vertical.end_pct)
		    .kv("max_abs_err_m", r.vertical.max_abs_err_m)
		    .kv("max_pct", r.vertical.max_pct);
		j.endObject();
	}
	else
	{
		j.key("association").null();
		j.key("ate").null();
		j.key("rpe").null();
		j.key("vertical_drift").null();
	}

	j.key("return_to_start").beginObject();
	j.key("estimate");
	writeClosure(j, r.return_to_start);
	j.key("gt");
	if (r.gt_return_to_start)
		writeClosure(j, *r.gt_return_to_start);
	else
		j.null();
	j.key("estimate_vs_gt");
	if (r.return_to_start_vs_gt)
		writeClosure(j, *r.return_to_start_vs_gt);
	else
		j.null();
	j.endObject();

	j.key("gnss_drift");
	if (r.gnss)
	{
		const auto& g = *r.gnss;
		j.beginObject();
		j.kv("t0_s", g.t0_s)
		    .kv("sample_times", g.sample_times)
		    .kv("samples", g.samples.size())
		    .kv("skipped_no_fix", g.skipped_no_fix);
		j.key("dist_3d_m");
		writeStats(j, g.dist_3d_m);
		j.key("dist_2d_m");
		writeStats(j, g.dist_2d_m);
		j.key("aligned_dist_3d_m");
		writeStats(j, g.aligned_dist_3d_m);
		j.key("alignment");
		writePose(j, g.alignment);
		j.key("points").beginArray();
		for (const auto& s : g.samples)
			j.beginObject()
			    .kv("t_s", s.t_s)
			    .kv("dist_3d_m", s.dist_3d_m)
			    .kv("dist_2d_m", s.dist_2d_m)
			    .endObject();
		j.endArray();
		j.endObject();
	}
	else
		j.null();
	j.endObject();
}

void writeTrajSvg(std::ostream& os, const TrajEvalInputs& in,
                  const TrajReport& r)
{
	const double inf = std::numeric_limits<double>::infinity();
	SvgPanel top(0, 0, 700, 650), prof(700, 0, 600, 650);
	const SvgStyle gt_style{"#000000", 1.5, "none", "", 1.0};
	const SvgStyle est_style{"#d62728", 1.5, "none", "", 1.0};
	const SvgStyle aligned_style{"#ff7f0e", 1.2, "none", "6,3", 1.0};
	const SvgStyle gnss_style{"#1f77b4", 1.2, "none", "", 1.0};

	std::vector<Eigen::Vector2d> gt_xy, est_xy, al_xy, gt_z, est_z, gnss_xy;
	double xmin = inf, xmax = -inf, ymin = inf, ymax = -inf;
	for (const auto& p : in.gt)
	{
		gt_xy.push_back(p.pose.translation().head<2>());
		SvgPanel::extend(gt_xy.back().x(), gt_xy.back().y(), xmin, xmax, ymin,
		                 ymax);
	}
	for (const auto& p : in.est)
	{
		est_xy.push_back(p.pose.translation().head<2>());
		SvgPanel::extend(est_xy.back().x(), est_xy.back().y(), xmin, xmax, ymin,
		                 ymax);
	}
	if (r.has_gt)
		for (const auto& p : in.est)
			al_xy.push_back(
			    (r.ate_aligned.alignment * p.pose).translation().head<2>());
	if (r.gnss)
		for (const auto& s : r.gnss->samples)
		{
			gnss_xy.push_back(s.gnss.head<2>());
			SvgPanel::extend(s.gnss.x(), s.gnss.y(), xmin, xmax, ymin, ymax);
		}
	top.setRange(xmin, xmax, ymin, ymax, true);
	top.polyline(gt_xy, gt_style);
	if (!al_xy.empty()) top.polyline(al_xy, aligned_style);
	top.polyline(est_xy, est_style);
	for (const auto& g : gnss_xy) top.circle(g.x(), g.y(), 3, gnss_style);
	if (!est_xy.empty())
		top.circle(est_xy.front().x(), est_xy.front().y(), 5,
		           SvgStyle{"#2ca02c", 2, "none", "", 1});
	top.axes("Top view", "x (m)", "y (m)");
	std::vector<std::pair<std::string, SvgStyle>> leg;
	if (r.has_gt) leg.push_back({"ground truth", gt_style});
	leg.push_back({"estimate", est_style});
	if (r.has_gt) leg.push_back({"estimate, SE(3) aligned", aligned_style});
	if (r.gnss) leg.push_back({"GNSS samples", gnss_style});
	leg.push_back({"start", SvgStyle{"#2ca02c", 2, "none", "", 1}});
	top.legend(leg);

	// Height profile against GT distance travelled, or time without GT.
	double pxmin = inf, pxmax = -inf, pymin = inf, pymax = -inf;
	std::string xlabel;
	if (r.has_gt)
	{
		const auto& pairs = r.association.pairs;
		const auto dist = gtDistanceTravelled(pairs);
		for (size_t i = 0; i < pairs.size(); i++)
		{
			gt_z.emplace_back(dist[i], pairs[i].gt.translation().z());
			est_z.emplace_back(dist[i], pairs[i].est.translation().z());
			SvgPanel::extend(dist[i], gt_z.back().y(), pxmin, pxmax, pymin,
			                 pymax);
			SvgPanel::extend(dist[i], est_z.back().y(), pxmin, pxmax, pymin,
			                 pymax);
		}
		xlabel = "GT distance travelled (m)";
	}
	else
	{
		for (const auto& p : in.est)
		{
			est_z.emplace_back(p.t_s - in.est.front().t_s,
			                   p.pose.translation().z());
			SvgPanel::extend(est_z.back().x(), est_z.back().y(), pxmin, pxmax,
			                 pymin, pymax);
		}
		if (r.gnss)
			for (const auto& s : r.gnss->samples)
			{
				gt_z.emplace_back(s.t_s - in.est.front().t_s, s.gnss.z());
				SvgPanel::extend(gt_z.back().x(), gt_z.back().y(), pxmin, pxmax,
				                 pymin, pymax);
			}
		xlabel = "time since first estimate (s)";
	}
	prof.setRange(pxmin, pxmax, pymin, pymax, false);
	if (r.has_gt)
		prof.polyline(gt_z, gt_style);
	else
		for (const auto& g : gt_z) prof.circle(g.x(), g.y(), 3, gnss_style);
	prof.polyline(est_z, est_style);
	prof.axes("Height profile", xlabel, "z (m)");
	writeSvgDocument(os, 1300, 650, {&top, &prof},
	                 "forest-eval traj: " + in.est_path);
}

}  // namespace forest_slam::eval
