#pragma once
// trees.csv: one row per tree, the columns of map::TreeRecord (doc/trees.md).
#include <forest_slam/map/forest_map.h>

#include <string>
#include <vector>

namespace forest_slam::trees
{
constexpr const char* kTreesCsvHeader =
    "id,x,y,z_ground,dbh_m,height_m,n_points,fit_rmse_m,arc_coverage_deg,n_"
    "slices,quality,path_distance_m";

/** Atomic write (temp file + rename); millimetre precision for lengths,
 * centimetres for path_distance_m (empty where unknown). */
void writeTreesCsv(const std::string& path,
                   const std::vector<map::TreeRecord>& trees);

}  // namespace forest_slam::trees
