#include <forest_slam/outputs/georeference.h>

#include <GeographicLib/LocalCartesian.hpp>
#include <GeographicLib/UTMUPS.hpp>

#include <cmath>
#include <stdexcept>

namespace forest_slam::outputs
{
std::optional<Georeference> Georeference::fromOptions(const GeoOptions& o)
{
	if (o.mode == "none") return std::nullopt;
	Georeference g;
	g.o_ = o;
	if (o.mode == "enu_origin")
	{
		g.enu_ = std::make_shared<GeographicLib::LocalCartesian>(
		    o.origin_lat_deg, o.origin_lon_deg, o.origin_alt_m);
		g.zone_ = GeographicLib::UTMUPS::StandardZone(o.origin_lat_deg,
		                                              o.origin_lon_deg);
		g.north_ = o.origin_lat_deg >= 0;
		if (g.zone_ < 1)
			throw std::invalid_argument(
			    "[georeference] origin is in a polar (UPS) region: UTM "
			    "outputs need |latitude| <= 84");
	}
	else if (o.mode == "utm")
	{
		if (o.utm_zone < 1 || o.utm_zone > 60)
			throw std::invalid_argument(
			    "[georeference] utm_zone must be 1..60");
		g.zone_ = o.utm_zone;
		g.north_ = o.utm_north;
	}
	else
		throw std::invalid_argument("[georeference] unknown mode '" + o.mode +
		                            "'");
	return g;
}

Eigen::Vector3d Georeference::toEnu(const Eigen::Vector3d& p) const
{
	if (o_.map_to_enu_yaw_rad == 0 && o_.map_to_enu_x_m == 0 &&
	    o_.map_to_enu_y_m == 0 && o_.map_to_enu_z_m == 0)
		return p;
	const double c = std::cos(o_.map_to_enu_yaw_rad),
	             s = std::sin(o_.map_to_enu_yaw_rad);
	return {c * p.x() - s * p.y() + o_.map_to_enu_x_m,
	        s * p.x() + c * p.y() + o_.map_to_enu_y_m,
	        p.z() + o_.map_to_enu_z_m};
}

Eigen::Vector3d Georeference::toProjected(const Eigen::Vector3d& map_xyz) const
{
	if (!enu_)
		return {map_xyz.x() + o_.utm_offset_e_m,
		        map_xyz.y() + o_.utm_offset_n_m,
		        map_xyz.z() + o_.utm_offset_h_m};
	const Eigen::Vector3d p = toEnu(map_xyz);
	double lat, lon, h, e, n, gamma, k;
	int zone;
	bool northp;
	enu_->Reverse(p.x(), p.y(), p.z(), lat, lon, h);
	GeographicLib::UTMUPS::Forward(lat, lon, zone, northp, e, n, gamma, k,
	                               zone_);
	// Forward reports the hemisphere of the point; keep the origin's
	// (northings south of the equator become negative, as in a fixed CRS).
	if (northp != north_) n += north_ ? -10000000.0 : 10000000.0;
	return {e, n, h};
}

LatLonAlt Georeference::toLatLon(const Eigen::Vector3d& p) const
{
	LatLonAlt r;
	if (enu_)
	{
		const Eigen::Vector3d q = toEnu(p);
		enu_->Reverse(q.x(), q.y(), q.z(), r.lat_deg, r.lon_deg, r.alt_m);
		return r;
	}
	const Eigen::Vector3d q = toProjected(p);
	GeographicLib::UTMUPS::Reverse(zone_, north_, q.x(), q.y(), r.lat_deg,
	                               r.lon_deg);
	r.alt_m = q.z();
	return r;
}

std::string Georeference::crsName() const
{
	return "WGS 84 / UTM zone " + std::to_string(zone_) + (north_ ? "N" : "S");
}

std::string Georeference::wkt() const
{
	const int cm = 6 * zone_ - 183;  // central meridian
	return "PROJCS[\"" + crsName() +
	       "\",GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS "
	       "84\",6378137,298.257223563,AUTHORITY[\"EPSG\",\"7030\"]],"
	       "AUTHORITY[\"EPSG\",\"6326\"]],PRIMEM[\"Greenwich\",0,AUTHORITY["
	       "\"EPSG\",\"8901\"]],UNIT[\"degree\",0.0174532925199433,"
	       "AUTHORITY[\"EPSG\",\"9122\"]],AUTHORITY[\"EPSG\",\"4326\"]],"
	       "PROJECTION[\"Transverse_Mercator\"],PARAMETER[\"latitude_of_"
	       "origin\",0],PARAMETER[\"central_meridian\"," +
	       std::to_string(cm) +
	       "],PARAMETER[\"scale_factor\",0.9996],PARAMETER[\"false_easting\","
	       "500000],PARAMETER[\"false_northing\"," +
	       (north_ ? "0" : "10000000") +
	       "],UNIT[\"metre\",1,AUTHORITY[\"EPSG\",\"9001\"]],AXIS["
	       "\"Easting\",EAST],AXIS[\"Northing\",NORTH],AUTHORITY[\"EPSG\",\"" +
	       std::to_string(epsg()) + "\"]]";
}

}  // namespace forest_slam::outputs
