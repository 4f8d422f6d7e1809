#pragma once
// trees.csv (the columns of libs/trees, plus projected coordinates and
// latitude/longitude when georeferenced) and trees.geojson for GIS tools.
#include <forest_slam/core/trajectory.h>
#include <forest_slam/map/forest_map.h>
#include <forest_slam/outputs/georeference.h>

#include <optional>
#include <string>
#include <vector>

namespace forest_slam::outputs
{
/** Columns added to trees::kTreesCsvHeader when georeferenced. */
constexpr const char* kTreesGeoColumns = "easting_m,northing_m,lat_deg,lon_deg";

/** Sets each tree's path_distance_m: its horizontal distance from the
 * polyline through the trajectory's positions (map frame). An empty
 * trajectory leaves them NaN. */
void setPathDistances(std::vector<map::TreeRecord>& trees,
                      const core::Trajectory& trajectory);

void writeTreesCsvGeo(const std::string& path,
                      const std::vector<map::TreeRecord>& trees,
                      const std::optional<Georeference>& geo);

/** GeoJSON FeatureCollection of Points with every TreeRecord field as a
 * property. Georeferenced: [lon, lat, z_ground] (RFC 7946, WGS 84);
 * otherwise [x, y, z_ground] in the map frame, which GIS tools show in a
 * local engineering CRS. Atomic write. */
void writeTreesGeoJson(const std::string& path,
                       const std::vector<map::TreeRecord>& trees,
                       const std::optional<Georeference>& geo);

}  // namespace forest_slam::outputs
