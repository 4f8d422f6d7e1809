#pragma once
// `forest-eval trees`: tree-map evaluation report (table, JSON, SVG).
#include <forest_slam/eval/tree_metrics.h>

#include <ostream>
#include <string>

namespace forest_slam::eval
{
struct TreeEvalInputs
{
	std::string gt_path, est_path, traj_path, regions_path;  ///< for the report
	std::vector<TreeRecord> gt, est;
	core::Trajectory traj;        ///< empty unless --traj
	std::vector<Region> regions;  ///< empty -> one region "all"
};

void printTreeReport(std::ostream& os, const TreeEvalInputs& in,
                     const TreeEvalOptions& opts, const TreeEvaluation& ev);
void writeTreeJson(std::ostream& os, const TreeEvalInputs& in,
                   const TreeEvalOptions& opts, const TreeEvaluation& ev);
/** Tree map (GT, estimates by status, match lines, trajectory) and DBH
 * estimated vs reference with the 1:1 line. */
void writeTreeSvg(std::ostream& os, const TreeEvalInputs& in,
                  const TreeEvalOptions& opts, const TreeEvaluation& ev);

}  // namespace forest_slam::eval
