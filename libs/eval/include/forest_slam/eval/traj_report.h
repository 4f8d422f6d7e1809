#pragma once
// `forest-eval traj`: every trajectory metric in one report, printed as a
// table, written as JSON and drawn as SVG. The app only parses arguments.
#include <forest_slam/eval/trajectory_metrics.h>

#include <optional>
#include <ostream>
#include <string>

namespace forest_slam::eval
{
struct TrajEvalInputs
{
	std::string gt_path, est_path, gnss_path;  ///< for the report only
	core::Trajectory gt;  ///< may be empty: then only the GT-free metrics
	core::Trajectory est;
	std::optional<PositionTrack> gnss;
};

struct TrajEvalOptions
{
	AssociationOptions association;
	RpeOptions rpe;
	GnssDriftOptions gnss;
};

struct TrajReport
{
	TrajEvalOptions options;
	bool has_gt = false;
	size_t gt_poses = 0, est_poses = 0;
	Association association;  ///< pairs kept for the SVG
	double gt_path_length_m = kNaN;
	AteResult ate_unaligned, ate_aligned;
	RpeResult rpe;
	VerticalDrift vertical;
	ReturnToStartError return_to_start;  ///< estimate's first vs last pose
	std::optional<ReturnToStartError> gt_return_to_start;  ///< same span
	std::optional<ReturnToStartError> return_to_start_vs_gt;
	std::optional<GnssDriftResult> gnss;
};

/** Throws std::runtime_error on empty inputs or no time overlap. */
TrajReport evaluateTrajectory(const TrajEvalInputs& in,
                              const TrajEvalOptions& opts);

void printTrajReport(std::ostream& os, const TrajEvalInputs& in,
                     const TrajReport& r);
void writeTrajJson(std::ostream& os, const TrajEvalInputs& in,
                   const TrajReport& r);
/** Top view (GT, estimate, aligned estimate, GNSS samples) and height
 * profile along the GT distance travelled. */
void writeTrajSvg(std::ostream& os, const TrajEvalInputs& in,
                  const TrajReport& r);

}  // namespace forest_slam::eval
