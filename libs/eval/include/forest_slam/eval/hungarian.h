#pragma once
// Optimal one-to-one assignment (Kuhn-Munkres / Hungarian algorithm with
// potentials, O(n^2 m)). Used for tree matching, where a greedy
// nearest-first match can steal a tree's only partner.
#include <Eigen/Core>

#include <vector>

namespace forest_slam::eval
{
/** Minimum-total-cost assignment for a rows x cols cost matrix.
 * Returns, for each row, the assigned column or -1. Exactly min(rows, cols)
 * rows are assigned. Throws std::invalid_argument on non-finite costs. */
std::vector<int> hungarian(const Eigen::MatrixXd& cost);

/** A pair of indices (a in the first set, b in the second) and their
 * distance. */
struct GatedMatch
{
	size_t a = 0, b = 0;
	double dist_m = 0;
};

/** One-to-one matching of two 2D point sets where a pair is allowed only if
 * its distance is <= gate_m: first the maximum number of pairs, then, among
 * those, the minimum sum of distances. Solved per connected component of
 * the gate graph (grid-bucketed), so thousands of trees stay fast.
 * Matches are sorted by `a`. */
std::vector<GatedMatch> matchGated(const std::vector<Eigen::Vector2d>& a,
                                   const std::vector<Eigen::Vector2d>& b,
                                   double gate_m);

}  // namespace forest_slam::eval
