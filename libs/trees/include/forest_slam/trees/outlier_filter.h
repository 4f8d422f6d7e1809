#pragma once
// Statistical outlier removal of a DBH slice (paper §4.2: mean distance to the
// k nearest neighbours, μ and σ over the slice, ω = 0.4, k = 10).
#include <forest_slam/trees/circle_fit.h>

#include <vector>

namespace forest_slam::trees
{
/** Indices of the points kept: those whose mean distance to their k nearest
 * neighbours is <= μ + ω·σ. The paper writes "outside μ ± ω·σ"; we drop
 * only the upper side, since an unusually *small* neighbour distance marks
 * the densest part of the stem, never an outlier. With fewer than k+1
 * points every point is kept. */
std::vector<size_t> statisticalOutlierFilter(const Points2D& p, int k,
                                             double omega);

}  // namespace forest_slam::trees
