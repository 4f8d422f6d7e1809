#pragma once
// Just enough SVG to draw the evaluation plots (trajectory top view, height
// profile, DBH scatter, tree map) without a plotting dependency.
#include <Eigen/Core>

#include <ostream>
#include <sstream>
#include <string>
#include <vector>

namespace forest_slam::eval
{
struct SvgStyle
{
	std::string stroke = "#000000";
	double width_px = 1.5;
	std::string fill = "none";
	std::string dash;  ///< SVG stroke-dasharray, e.g. "6,3"
	double opacity = 1.0;
};

/** One x/y plot inside an SVG document: data coordinates are mapped to the
 * panel's pixel rectangle (y up). */
class SvgPanel
{
   public:
	/** Pixel rectangle of the whole panel (axes labels included). */
	SvgPanel(double left_px, double top_px, double width_px, double height_px);

	/** Data range; adds a small margin; equal_aspect keeps 1 m = 1 m. */
	void setRange(double xmin, double xmax, double ymin, double ymax,
	              bool equal_aspect);
	/** Extends a running bounding box (call before setRange). */
	static void extend(double x, double y, double& xmin, double& xmax,
	                   double& ymin, double& ymax);

	void polyline(const std::vector<Eigen::Vector2d>& pts, const SvgStyle& s);
	void line(double x0, double y0, double x1, double y1, const SvgStyle& s);
	void circle(double x, double y, double radius_px, const SvgStyle& s);
	void cross(double x, double y, double half_px, const SvgStyle& s);
	/** Frame, ticks with values, axis labels and title. */
	void axes(const std::string& title, const std::string& xlabel,
	          const std::string& ylabel);
	void legend(const std::vector<std::pair<std::string, SvgStyle>>& entries);

	const std::string& body() const { return body_; }

	double px(double x) const;
	double py(double y) const;

   private:
	double left_, top_, width_, height_;
	double plot_l_, plot_t_, plot_w_, plot_h_;  // inner plotting area
	double xmin_ = 0, xmax_ = 1, ymin_ = 0, ymax_ = 1;
	std::string body_;
};

/** Writes a complete SVG document holding the panels. */
void writeSvgDocument(std::ostream& os, double width_px, double height_px,
                      const std::vector<const SvgPanel*>& panels,
                      const std::string& title);

std::string svgEscape(const std::string& s);

}  // namespace forest_slam::eval
