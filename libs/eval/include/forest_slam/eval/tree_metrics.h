#pragma once
// Tree-map metrics: one-to-one matching, detection scores, position and DBH
// errors with the paper's formulas (§6.2, Tables 3-4). Definitions:
// doc/evaluation.md.
#include <forest_slam/core/trajectory.h>
#include <forest_slam/eval/hungarian.h>
#include <forest_slam/eval/stats.h>

#include <Eigen/Core>

#include <string>
#include <vector>

namespace forest_slam::eval
{
struct TreeRecord
{
	std::string id;
	double x = 0, y = 0;
	double dbh_m = 0;
	bool sapling = false;
	size_t line = 0;  ///< line in the source file, for messages
};

/** CSV with a header; columns id,x,y,dbh_m are required, `sapling` is read
 * if present (0/1/true/false), all others are ignored. DBH must be >= 0.
 * Throws naming file:line:column. */
std::vector<TreeRecord> readTreesCsv(const std::string& path);

struct Region
{
	std::string name;
	double xmin = 0, ymin = 0, xmax = 0, ymax = 0;
	bool contains(double x, double y) const
	{
		return x >= xmin && x <= xmax && y >= ymin && y <= ymax;
	}
};

/** CSV with columns name,xmin,ymin,xmax,ymax (xmin <= xmax, ymin <= ymax,
 * unique names). Throws naming file:line:column. */
std::vector<Region> readRegionsCsv(const std::string& path);

/** A region covering the whole plane, named "all". */
Region allRegion();

/** Paper §6.2 with x = predicted, y = actual (N pairs):
 * RMSE = sqrt(mean((x-y)^2)), MAE = mean|x-y|, MAPE = 100 mean|1 - x/y|,
 * bias = mean(x-y); rel_* divide by mean(y). */
struct DbhErrors
{
	size_t count = 0;
	double rmse_m = kNaN, mae_m = kNaN, mape_pct = kNaN, bias_m = kNaN;
	double rel_rmse_pct = kNaN, rel_bias_pct = kNaN;
};

/** Throws std::invalid_argument if the sizes differ. MAPE is NaN if any
 * actual value is 0. */
DbhErrors dbhErrors(const std::vector<double>& predicted_m,
                    const std::vector<double>& actual_m);

/** Hungarian matching on horizontal distance with a gate (matchGated):
 * maximum number of pairs, then minimum total distance. */
std::vector<GatedMatch> matchTrees(const std::vector<TreeRecord>& gt,
                                   const std::vector<TreeRecord>& est,
                                   double max_match_m);

/** Horizontal distance from (x, y) to the polyline through the trajectory
 * positions, accelerated with a grid whose cell is `cell_m`. */
class TrajectoryCorridor
{
   public:
	TrajectoryCorridor(const core::Trajectory& traj, double cell_m);
	/** Exact distance (scans every segment when none is within cell_m). */
	double distance(double x, double y) const;
	/** distance(x, y) <= cell_m, looking only at nearby grid cells. */
	bool within(double x, double y) const;

   private:
	/** Nearest segment among those registered in the +-2 nearby cells. */
	double nearbyDistance(double x, double y) const;
	struct Segment
	{
		Eigen::Vector2d a, b;
	};
	double cell_m_;
	std::vector<Segment> segments_;
	std::vector<std::pair<std::pair<int64_t, int64_t>, size_t>>
	    cells_;  // sorted
};

enum class GtTreeStatus
{
	Evaluated,
	Sapling,
	BelowMinDbh,
	OutOfRange
};

enum class EstTreeStatus
{
	TruePositive,     ///< matched to an evaluated GT tree
	FalsePositive,    ///< unmatched, inside the evaluated area
	MatchedExcluded,  ///< matched to a GT tree that is not evaluated: ignored
	OutOfRange        ///< unmatched, outside the evaluated area: ignored
};

const char* toString(GtTreeStatus s);
const char* toString(EstTreeStatus s);

struct TreeEvalOptions
{
	double max_match_m = 0.5;
	double min_dbh_m = 0.10;
	/** Evaluated area: horizontal distance to `traj` <= max_range_m; <= 0 or
	 * an empty trajectory disables the range rule. */
	double max_range_m = 0;
};

struct RegionTreeStats
{
	Region region;
	size_t measured_count = 0;  ///< evaluated GT trees in the region
	SummaryStats measured_dbh_m;
	size_t estimated_count = 0;  ///< TP (by GT position) + FP (own position)
	SummaryStats estimated_dbh_m;
	size_t tp = 0, fn = 0, fp = 0;
	double recall = kNaN, precision = kNaN, f1 = kNaN;
	DbhErrors dbh;  ///< over the region's true positives
};

/** How much of the position error is systematic (over the true positives,
 * horizontal): a common offset, or a 2D similarity of the whole map (its
 * scale and rotation about the trees' centroid, as a trajectory's drift or
 * a scale bias of the odometry make). The target figures stay the raw
 * distances; this says what the raw RMSE is made of. */
struct PositionErrorStructure
{
	size_t count = 0;  ///< true positives used (fitted from 3 on)
	double offset_x_m = kNaN, offset_y_m = kNaN;  ///< mean est - GT
	double rmse_after_offset_m = kNaN;
	/** est ~= scale * R(rotation) * gt + t, least squares (Umeyama). */
	double scale = kNaN, rotation_deg = kNaN;
	double rmse_after_similarity_m = kNaN;
};

/** Fits the structure to matched positions (gt[i] <-> est[i]); NaNs below
 * three pairs. */
PositionErrorStructure positionErrorStructure(
    const std::vector<Eigen::Vector2d>& gt,
    const std::vector<Eigen::Vector2d>& est);

struct TreeEvaluation
{
	std::vector<GtTreeStatus> gt_status;
	std::vector<EstTreeStatus> est_status;
	/** All Hungarian pairs (gt index a, est index b), including pairs with
	 * excluded GT trees. */
	std::vector<GatedMatch> matches;
	std::vector<GatedMatch> true_positives;
	size_t gt_evaluated = 0, gt_sapling = 0, gt_below_min_dbh = 0,
	       gt_out_of_range = 0;
	size_t tp = 0, fn = 0, fp = 0, est_matched_excluded = 0,
	       est_out_of_range = 0;
	double recall = kNaN, precision = kNaN, f1 = kNaN;
	SummaryStats position_err_m;  ///< horizontal distance over TPs
	PositionErrorStructure position_structure;
	DbhErrors dbh;
	std::vector<RegionTreeStats> regions;
};

/** GT trees are evaluated unless sapling, DBH below min_dbh_m (or 0), or
 * farther than max_range_m from the trajectory; matching uses all GT trees so
 * that an estimate of an excluded tree is ignored instead of counted as a
 * false positive; an unmatched estimate is a false positive only inside the
 * evaluated area (same range rule on its own position). */
TreeEvaluation evaluateTrees(
    const std::vector<TreeRecord>& gt, const std::vector<TreeRecord>& est,
    const TreeEvalOptions& opts, const core::Trajectory& traj = {},
    const std::vector<Region>& regions = {allRegion()});

/** recall = tp/(tp+fn), precision = tp/(tp+fp), F1 = harmonic mean; NaN
 * when a denominator is 0. */
void detectionScores(size_t tp, size_t fn, size_t fp, double& recall,
                     double& precision, double& f1);

}  // namespace forest_slam::eval
