#include <forest_slam/eval/csv_table.h>
#include <forest_slam/eval/tree_metrics.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <set>
#include <stdexcept>

namespace forest_slam::eval
{
std::vector<TreeRecord> readTreesCsv(const std::string& path)
{
	const CsvTable csv = CsvTable::read(path);
	const size_t cid = csv.column("id"), cx = csv.column("x"),
	             cy = csv.column("y"), cd = csv.column("dbh_m");
	const auto cs = csv.findColumn("sapling");
	std::vector<TreeRecord> trees;
	for (size_t r = 0; r < csv.rows(); r++)
	{
		TreeRecord t;
		t.id = csv.cell(r, cid);
		t.x = csv.number(r, cx);
		t.y = csv.number(r, cy);
		t.dbh_m = csv.number(r, cd);
		if (t.dbh_m < 0)
			throw std::runtime_error(csv.where(r, cd) +
			                         ": expected a DBH >= 0 in metres, got '" +
			                         csv.cell(r, cd) + "'");
		if (cs) t.sapling = csv.boolean(r, *cs);
		t.line = csv.lineOf(r);
		trees.push_back(t);
	}
	return trees;
}

std::vector<Region> readRegionsCsv(const std::string& path)
{
	const CsvTable csv = CsvTable::read(path);
	const size_t cn = csv.column("name"), c0 = csv.column("xmin"),
	             c1 = csv.column("ymin"), c2 = csv.column("xmax"),
	             c3 = csv.column("ymax");
	std::vector<Region> out;
	std::set<std::string> names;
	for (size_t r = 0; r < csv.rows(); r++)
	{
		Region g;
		g.name = csv.cell(r, cn);
		if (g.name.empty())
			throw std::runtime_error(csv.where(r, cn) + ": empty region name");
		if (!names.insert(g.name).second)
			throw std::runtime_error(csv.where(r, cn) + ": region '" + g.name +
			                         "' defined twice");
		g.xmin = csv.number(r, c0);
		g.ymin = csv.number(r, c1);
		g.xmax = csv.number(r, c2);
		g.ymax = csv.number(r, c3);
		if (g.xmin > g.xmax)
			throw std::runtime_error(csv.where(r, c2) +
			                         ": expected xmax >= xmin");
		if (g.ymin > g.ymax)
			throw std::runtime_error(csv.where(r, c3) +
			                         ": expected ymax >= ymin");
		out.push_back(g);
	}
	if (out.empty())
		throw std::runtime_error(path + ": no region rows after the header");
	return out;
}

Region allRegion()
{
	const double inf = std::numeric_limits<double>::infinity();
	return Region{"all", -inf, -inf, inf, inf};
}

DbhErrors dbhErrors(const std::vector<double>& x, const std::vector<double>& y)
{
	if (x.size() != y.size())
		throw std::invalid_argument(
		    "dbhErrors: predicted and actual differ in size");
	DbhErrors e;
	e.count = x.size();
	if (x.empty()) return e;
	double sq = 0, ab = 0, ape = 0, bias = 0, sum_y = 0;
	bool mape_ok = true;
	for (size_t i = 0; i < x.size(); i++)
	{
		const double d = x[i] - y[i];
		sq += d * d;
		ab += std::abs(d);
		bias += d;
		sum_y += y[i];
		if (y[i] == 0)
			mape_ok = false;
		else
			ape += std::abs(1.0 - x[i] / y[i]);
	}
	const double n = static_cast<double>(x.size());
	e.rmse_m = std::sqrt(sq / n);
	e.mae_m = ab / n;
	e.bias_m = bias / n;
	if (mape_ok) e.mape_pct = 100.0 * ape / n;
	const double mean_y = sum_y / n;
	if (mean_y != 0)
	{
		e.rel_rmse_pct = 100.0 * e.rmse_m / mean_y;
		e.rel_bias_pct = 100.0 * e.bias_m / mean_y;
	}
	return e;
}

std::vector<GatedMatch> matchTrees(const std::vector<TreeRecord>& gt,
                                   const std::vector<TreeRecord>& est,
                                   double max_match_m)
{
	std::vector<Eigen::Vector2d> a, b;
	for (const auto& t : gt) a.emplace_back(t.x, t.y);
	for (const auto& t : est) b.emplace_back(t.x, t.y);
	return matchGated(a, b, max_match_m);
}

namespace
{
std::pair<int64_t, int64_t> cellKey(double x, double y, double cell)
{
	return {static_cast<int64_t>(std::floor(x / cell)),
	        static_cast<int64_t>(std::floor(y / cell))};
}

double pointSegmentDistance(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                            const Eigen::Vector2d& b)
{
	const Eigen::Vector2d ab = b - a;
	const double len2 = ab.squaredNorm();
	const double t =
	    len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
	return (a + t * ab - p).norm();
}
}  // namespace

TrajectoryCorridor::TrajectoryCorridor(const core::Trajectory& traj,
                                       double cell_m)
    : cell_m_(cell_m)
{
	if (!(cell_m > 0))
		throw std::invalid_argument("TrajectoryCorridor: cell must be > 0");
	std::vector<Eigen::Vector2d> pts;
	for (const auto& p : traj) pts.push_back(p.pose.translation().head<2>());
	if (pts.size() == 1) pts.push_back(pts[0]);
	for (size_t i = 1; i < pts.size(); i++)
	{
		const size_t s = segments_.size();
		segments_.push_back({pts[i - 1], pts[i]});
		// Register the segment in the cells of samples <= cell/2 apart: every
		// point of it is then within cell/4 of a registered cell, so a query
		// scanning +-2 cells finds all segments within cell_m.
		const double len = (pts[i] - pts[i - 1]).norm();
		const int n = 1 + static_cast<int>(std::ceil(len / (0.5 * cell_m)));
		std::pair<int64_t, int64_t> last{INT64_MIN, INT64_MIN};
		for (int k = 0; k <= n; k++)
		{
			const Eigen::Vector2d q =
			    pts[i - 1] + (pts[i] - pts[i - 1]) * (double(k) / n);
			const auto key = cellKey(q.x(), q.y(), cell_m);
			if (key == last) continue;
			cells_.push_back({key, s});
			last = key;
		}
	}
	std::sort(cells_.begin(), cells_.end());
	cells_.erase(std::unique(cells_.begin(), cells_.end()), cells_.end());
}

double TrajectoryCorridor::nearbyDistance(double x, double y) const
{
	const Eigen::Vector2d p(x, y);
	double best = std::numeric_limits<double>::infinity();
	const auto c = cellKey(x, y, cell_m_);
	for (int64_t dx = -2; dx <= 2; dx++)
		for (int64_t dy = -2; dy <= 2; dy++)
		{
			const std::pair<int64_t, int64_t> key{c.first + dx, c.second + dy};
			auto it = std::lower_bound(cells_.begin(), cells_.end(),
			                           std::make_pair(key, size_t{0}));
			for (; it != cells_.end() && it->first == key; ++it)
			{
				const auto& s = segments_[it->second];
				best = std::min(best, pointSegmentDistance(p, s.a, s.b));
			}
		}
	return best;
}

bool TrajectoryCorridor::within(double x, double y) const
{
	return nearbyDistance(x, y) <= cell_m_;
}

double TrajectoryCorridor::distance(double x, double y) const
{
	// Only segments within cell_m are guaranteed to be in the scanned cells;
	// a farther nearby hit may not be the nearest one.
	double best = nearbyDistance(x, y);
	if (best <= cell_m_) return best;
	for (const auto& s : segments_)
		best = std::min(best,
		                pointSegmentDistance(Eigen::Vector2d(x, y), s.a, s.b));
	return best;
}

const char* toString(GtTreeStatus s)
{
	switch (s)
	{
		case GtTreeStatus::Evaluated:
			return "evaluated";
		case GtTreeStatus::Sapling:
			return "sapling";
		case GtTreeStatus::BelowMinDbh:
			return "below_min_dbh";
		case GtTreeStatus::OutOfRange:
			return "out_of_range";
	}
	return "?";
}

const char* toString(EstTreeStatus s)
{
	switch (s)
	{
		case EstTreeStatus::TruePositive:
			return "true_positive";
		case EstTreeStatus::FalsePositive:
			return "false_positive";
		case EstTreeStatus::MatchedExcluded:
			return "matched_excluded";
		case EstTreeStatus::OutOfRange:
			return "out_of_range";
	}
	return "?";
}

void detectionScores(size_t tp, size_t fn, size_t fp, double& recall,
                     double& precision, double& f1)
{
	recall = tp + fn ? double(tp) / double(tp + fn) : kNaN;
	precision = tp + fp ? double(tp) / double(tp + fp) : kNaN;
	f1 = (tp + fn && tp + fp && recall + precision > 0)
	         ? 2 * recall * precision / (recall + precision)
	         : (tp + fn && tp + fp ? 0.0 : kNaN);
}

PositionErrorStructure positionErrorStructure(
    const std::vector<Eigen::Vector2d>& gt,
    const std::vector<Eigen::Vector2d>& est)
{
	if (gt.size() != est.size())
		throw std::invalid_argument(
		    "positionErrorStructure: as many estimates as GT positions");
	PositionErrorStructure out;
	const size_t n = gt.size();
	out.count = n;
	if (n < 3) return out;
	Eigen::Matrix2Xd G(2, n), E(2, n);
	for (size_t i = 0; i < n; i++) G.col(i) = gt[i], E.col(i) = est[i];
	const Eigen::Vector2d offset = (E - G).rowwise().mean();
	out.offset_x_m = offset.x();
	out.offset_y_m = offset.y();
	auto rmse = [&](const Eigen::Matrix2Xd& fitted)
	{ return std::sqrt((E - fitted).colwise().squaredNorm().mean()); };
	out.rmse_after_offset_m = rmse(G.colwise() + offset);
	// The 2D similarity in closed form (Umeyama in the plane): about the
	// centroids, the rotation from the summed dot and cross products, the
	// scale from their norm over the GT's spread. (Eigen::umeyama, which
	// umeyamaSe3 uses in 3D, draws GCC 12's -Wstringop-overread on 2x2.)
	const Eigen::Vector2d cg = G.rowwise().mean(), ce = E.rowwise().mean();
	const Eigen::Matrix2Xd g = G.colwise() - cg, e = E.colwise() - ce;
	const double dot = (g.array() * e.array()).sum();
	const double cross = (g.row(0).array() * e.row(1).array() -
	                      g.row(1).array() * e.row(0).array())
	                         .sum();
	const double spread = g.squaredNorm();
	if (!(spread > 0)) return out;
	const double angle = std::atan2(cross, dot);
	out.scale = std::hypot(dot, cross) / spread;
	out.rotation_deg = angle * 180.0 / M_PI;
	const Eigen::Matrix2d sR =
	    out.scale * Eigen::Rotation2Dd(angle).toRotationMatrix();
	out.rmse_after_similarity_m = rmse((sR * g).colwise() + ce);
	return out;
}

TreeEvaluation evaluateTrees(const std::vector<TreeRecord>& gt,
                             const std::vector<TreeRecord>& est,
                             const TreeEvalOptions& opts,
                             const core::Trajectory& traj,
                             const std::vector<Region>& regions)
{
	if (!(opts.max_match_m > 0))
		throw std::invalid_argument("max_match_m must be > 0");
	TreeEvaluation ev;
	const bool use_range = opts.max_range_m > 0 && !traj.empty();
	std::unique_ptr<TrajectoryCorridor> corridor;
	if (use_range)
		corridor = std::make_unique<TrajectoryCorridor>(traj, opts.max_range_m);
	auto inRange = [&](double x, double y)
	{ return !use_range || corridor->within(x, y); };

	for (const auto& t : gt)
	{
		GtTreeStatus s = GtTreeStatus::Evaluated;
		if (!inRange(t.x, t.y))
			s = GtTreeStatus::OutOfRange;
		else if (t.sapling)
			s = GtTreeStatus::Sapling;
		else if (t.dbh_m < opts.min_dbh_m || t.dbh_m <= 0)
			s = GtTreeStatus::BelowMinDbh;
		ev.gt_status.push_back(s);
		switch (s)
		{
			case GtTreeStatus::Evaluated:
				ev.gt_evaluated++;
				break;
			case GtTreeStatus::Sapling:
				ev.gt_sapling++;
				break;
			case GtTreeStatus::BelowMinDbh:
				ev.gt_below_min_dbh++;
				break;
			case GtTreeStatus::OutOfRange:
				ev.gt_out_of_range++;
				break;
		}
	}

	ev.matches = matchTrees(gt, est, opts.max_match_m);
	std::vector<int> est_partner(est.size(), -1), gt_partner(gt.size(), -1);
	for (const auto& m : ev.matches)
	{
		est_partner[m.b] = static_cast<int>(m.a);
		gt_partner[m.a] = static_cast<int>(m.b);
	}
	for (size_t j = 0; j < est.size(); j++)
	{
		EstTreeStatus s;
		if (est_partner[j] >= 0)
			s = ev.gt_status[est_partner[j]] == GtTreeStatus::Evaluated
			        ? EstTreeStatus::TruePositive
			        : EstTreeStatus::MatchedExcluded;
		else
			s = inRange(est[j].x, est[j].y) ? EstTreeStatus::FalsePositive
			                                : EstTreeStatus::OutOfRange;
		ev.est_status.push_back(s);
		switch (s)
		{
			case EstTreeStatus::TruePositive:
				ev.tp++;
				break;
			case EstTreeStatus::FalsePositive:
				ev.fp++;
				break;
			case EstTreeStatus::MatchedExcluded:
				ev.est_matched_excluded++;
				break;
			case EstTreeStatus::OutOfRange:
				ev.est_out_of_range++;
				break;
		}
	}
	for (size_t i = 0; i < gt.size(); i++)
		if (ev.gt_status[i] == GtTreeStatus::Evaluated && gt_partner[i] < 0)
			ev.fn++;
	detectionScores(ev.tp, ev.fn, ev.fp, ev.recall, ev.precision, ev.f1);

	std::vector<double> pos, x, y;
	std::vector<Eigen::Vector2d> gt_xy, est_xy;
	for (const auto& m : ev.matches)
	{
		if (ev.gt_status[m.a] != GtTreeStatus::Evaluated) continue;
		ev.true_positives.push_back(m);
		pos.push_back(m.dist_m);
		x.push_back(est[m.b].dbh_m);
		y.push_back(gt[m.a].dbh_m);
		gt_xy.emplace_back(gt[m.a].x, gt[m.a].y);
		est_xy.emplace_back(est[m.b].x, est[m.b].y);
	}
	ev.position_err_m = summarize(pos);
	ev.position_structure = positionErrorStructure(gt_xy, est_xy);
	ev.dbh = dbhErrors(x, y);

	for (const auto& region : regions)
	{
		RegionTreeStats rs;
		rs.region = region;
		std::vector<double> meas, estd, rx, ry;
		for (size_t i = 0; i < gt.size(); i++)
		{
			if (ev.gt_status[i] != GtTreeStatus::Evaluated ||
			    !region.contains(gt[i].x, gt[i].y))
				continue;
			meas.push_back(gt[i].dbh_m);
			if (gt_partner[i] < 0)
				rs.fn++;
			else
			{
				const auto& e = est[static_cast<size_t>(gt_partner[i])];
				rs.tp++;
				estd.push_back(e.dbh_m);
				rx.push_back(e.dbh_m);
				ry.push_back(gt[i].dbh_m);
			}
		}
		for (size_t j = 0; j < est.size(); j++)
			if (ev.est_status[j] == EstTreeStatus::FalsePositive &&
			    region.contains(est[j].x, est[j].y))
			{
				rs.fp++;
				estd.push_back(est[j].dbh_m);
			}
		rs.measured_count = meas.size();
		rs.measured_dbh_m = summarize(meas);
		rs.estimated_count = estd.size();
		rs.estimated_dbh_m = summarize(estd);
		detectionScores(rs.tp, rs.fn, rs.fp, rs.recall, rs.precision, rs.f1);
		rs.dbh = dbhErrors(rx, ry);
		ev.regions.push_back(rs);
	}
	return ev;
}

}  // namespace forest_slam::eval
