#include <forest_slam/core/atomic_file.h>
#include <forest_slam/trees/tree_csv.h>

#include <cmath>
#include <cstdio>

namespace forest_slam::trees
{
void writeTreesCsv(const std::string& path,
                   const std::vector<map::TreeRecord>& trees)
{
	core::writeFileAtomically(
	    path,
	    [&](std::ostream& os)
	    {
		    os << kTreesCsvHeader << "\n";
		    char line[512];
		    for (const auto& t : trees)
		    {
			    std::snprintf(line, sizeof(line),
			                  "%u,%.4f,%.4f,%.4f,%.4f,%.3f,%u,%.4f,%.1f,%u,%u,",
			                  unsigned(t.id), t.x, t.y, t.z_ground, t.dbh_m,
			                  t.height_m, unsigned(t.n_points), t.fit_rmse_m,
			                  t.arc_coverage_deg, unsigned(t.n_slices),
			                  unsigned(t.quality));
			    os << line;
			    if (std::isfinite(t.path_distance_m))
			    {
				    std::snprintf(line, sizeof(line), "%.2f",
				                  t.path_distance_m);
				    os << line;
			    }
			    os << "\n";
		    }
	    });
}

}  // namespace forest_slam::trees
