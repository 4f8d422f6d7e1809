#pragma once
// Map frame -> projected (UTM, WGS 84) coordinates and latitude/longitude,
// for the outputs GIS tools open (LAS with a WKT CRS, dtm.asc, trees.csv and
// trees.geojson). Built from [georeference] (GeoOptions).
#include <forest_slam/outputs/output_options.h>

#include <Eigen/Core>
#include <memory>
#include <optional>
#include <string>

namespace GeographicLib
{
class LocalCartesian;
}

namespace forest_slam::outputs
{
struct LatLonAlt
{
	double lat_deg = 0, lon_deg = 0, alt_m = 0;
};

class Georeference
{
   public:
	/** nullopt for mode=none; throws std::invalid_argument on bad options. */
	static std::optional<Georeference> fromOptions(const GeoOptions& o);

	/** Easting, northing [m] in the UTM zone, ellipsoidal height [m]. */
	Eigen::Vector3d toProjected(const Eigen::Vector3d& map_xyz) const;
	LatLonAlt toLatLon(const Eigen::Vector3d& map_xyz) const;
	/** enu_origin: East-North-Up at the origin (the map frame itself
	 * unless the options carry an estimated map->ENU transform). */
	Eigen::Vector3d toEnu(const Eigen::Vector3d& map_xyz) const;

	int utmZone() const { return zone_; }
	bool north() const { return north_; }
	/** EPSG code of "WGS 84 / UTM zone NN{N,S}" (326NN / 327NN). */
	int epsg() const { return (north_ ? 32600 : 32700) + zone_; }
	std::string crsName() const;
	/** OGC WKT 1 of the projected CRS (LAS 1.4 WKT VLR, record 2112). */
	std::string wkt() const;

   private:
	Georeference() = default;
	GeoOptions o_;
	int zone_ = 0;
	bool north_ = true;
	std::shared_ptr<const GeographicLib::LocalCartesian> enu_;
};

}  // namespace forest_slam::outputs
