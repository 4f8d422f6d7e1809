#include <forest_slam/eval/svg_plot.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace forest_slam::eval
{
namespace
{
std::string num(double v)
{
	char buf[32];
	std::snprintf(buf, sizeof(buf), "%.1f", v);
	return buf;
}

std::string styleAttrs(const SvgStyle& s)
{
	std::string a = " stroke=\"" + s.stroke + "\" stroke-width=\"" +
	                num(s.width_px) + "\" fill=\"" + s.fill + "\"";
	if (!s.dash.empty()) a += " stroke-dasharray=\"" + s.dash + "\"";
	if (s.opacity < 1) a += " opacity=\"" + std::to_string(s.opacity) + "\"";
	return a;
}

/** 1-2-5 tick step giving about `target` intervals over `range`. */
double niceStep(double range, int target)
{
	const double raw = range / target;
	const double mag = std::pow(10.0, std::floor(std::log10(raw)));
	for (double m : {1.0, 2.0, 5.0, 10.0})
		if (m * mag >= raw) return m * mag;
	return 10 * mag;
}

std::string tickLabel(double v, double step)
{
	char buf[32];
	const int decimals =
	    step >= 1 ? 0 : static_cast<int>(std::ceil(-std::log10(step)));
	std::snprintf(buf, sizeof(buf), "%.*f", decimals,
	              std::abs(v) < 1e-12 ? 0.0 : v);
	return buf;
}
}  // namespace

std::string svgEscape(const std::string& s)
{
	std::string out;
	for (char c : s)
	{
		if (c == '<')
			out += "&lt;";
		else if (c == '>')
			out += "&gt;";
		else if (c == '&')
			out += "&amp;";
		else if (c == '"')
			out += "&quot;";
		else
			out += c;
	}
	return out;
}

SvgPanel::SvgPanel(double left_px, double top_px, double width_px,
                   double height_px)
    : left_(left_px), top_(top_px), width_(width_px), height_(height_px)
{
	// Room for the title above and tick labels / axis names left and below.
	plot_l_ = left_ + 70;
	plot_t_ = top_ + 35;
	plot_w_ = std::max(10.0, width_ - 90);
	plot_h_ = std::max(10.0, height_ - 85);
}

void SvgPanel::extend(double x, double y, double& xmin, double& xmax,
                      double& ymin, double& ymax)
{
	if (!std::isfinite(x) || !std::isfinite(y)) return;
	xmin = std::min(xmin, x);
	xmax = std::max(xmax, x);
	ymin = std::min(ymin, y);
	ymax = std::max(ymax, y);
}

void SvgPanel::setRange(double xmin, double xmax, double ymin, double ymax,
                        bool equal_aspect)
{
	if (!(xmin <= xmax)) xmin = 0, xmax = 1;
	if (!(ymin <= ymax)) ymin = 0, ymax = 1;
	double w = std::max(xmax - xmin, 1e-6), h = std::max(ymax - ymin, 1e-6);
	xmin -= 0.05 * w, xmax += 0.05 * w, ymin -= 0.05 * h, ymax += 0.05 * h;
	w *= 1.1, h *= 1.1;
	if (equal_aspect)
	{
		const double scale = std::max(w / plot_w_, h / plot_h_);
		const double cx = 0.5 * (xmin + xmax), cy = 0.5 * (ymin + ymax);
		xmin = cx - 0.5 * scale * plot_w_, xmax = cx + 0.5 * scale * plot_w_;
		ymin = cy - 0.5 * scale * plot_h_, ymax = cy + 0.5 * scale * plot_h_;
	}
	xmin_ = xmin, xmax_ = xmax, ymin_ = ymin, ymax_ = ymax;
}

double SvgPanel::px(double x) const
{
	return plot_l_ + (x - xmin_) / (xmax_ - xmin_) * plot_w_;
}

double SvgPanel::py(double y) const
{
	return plot_t_ + (ymax_ - y) / (ymax_ - ymin_) * plot_h_;
}

void SvgPanel::polyline(const std::vector<Eigen::Vector2d>& pts,
                        const SvgStyle& s)
{
	if (pts.empty()) return;
	// Points closer than half a pixel to the last drawn one add bytes, not
	// detail (a 100 Hz ground truth has ~100k of them).
	std::string p;
	double lx = 1e300, ly = 1e300;
	for (size_t i = 0; i < pts.size(); i++)
	{
		const double x = px(pts[i].x()), y = py(pts[i].y());
		if (i + 1 < pts.size() && std::hypot(x - lx, y - ly) < 0.5) continue;
		p += num(x) + "," + num(y) + " ";
		lx = x, ly = y;
	}
	body_ += "<polyline points=\"" + p + "\"" + styleAttrs(s) +
	         " stroke-linejoin=\"round\"/>\n";
}

void SvgPanel::line(double x0, double y0, double x1, double y1,
                    const SvgStyle& s)
{
	body_ += "<line x1=\"" + num(px(x0)) + "\" y1=\"" + num(py(y0)) +
	         "\" x2=\"" + num(px(x1)) + "\" y2=\"" + num(py(y1)) + "\"" +
	         styleAttrs(s) + "/>\n";
}

void SvgPanel::circle(double x, double y, double r, const SvgStyle& s)
{
	body_ += "<circle cx=\"" + num(px(x)) + "\" cy=\"" + num(py(y)) +
	         "\" r=\"" + num(r) + "\"" + styleAttrs(s) + "/>\n";
}

void SvgPanel::cross(double x, double y, double h, const SvgStyle& s)
{
	const double cx = px(x), cy = py(y);
	body_ += "<path d=\"M" + num(cx - h) + "," + num(cy - h) + " L" +
	         num(cx + h) + "," + num(cy + h) + " M" + num(cx - h) + "," +
	         num(cy + h) + " L" + num(cx + h) + "," + num(cy - h) + "\"" +
	         styleAttrs(s) + "/>\n";
}

void SvgPanel::axes(const std::string& title, const std::string& xlabel,
                    const std::string& ylabel)
{
	std::string a;
	a += "<rect x=\"" + num(plot_l_) + "\" y=\"" + num(plot_t_) +
	     "\" width=\"" + num(plot_w_) + "\" height=\"" + num(plot_h_) +
	     "\" fill=\"none\" stroke=\"#444\"/>\n";
	const double xs = niceStep(xmax_ - xmin_, 6),
	             ys = niceStep(ymax_ - ymin_, 6);
	for (double v = std::ceil(xmin_ / xs) * xs; v <= xmax_; v += xs)
	{
		const double x = px(v);
		a += "<line x1=\"" + num(x) + "\" y1=\"" + num(plot_t_) + "\" x2=\"" +
		     num(x) + "\" y2=\"" + num(plot_t_ + plot_h_) +
		     "\" stroke=\"#e4e4e4\"/>\n";
		a += "<text x=\"" + num(x) + "\" y=\"" + num(plot_t_ + plot_h_ + 16) +
		     "\" text-anchor=\"middle\">" + tickLabel(v, xs) + "</text>\n";
	}
	for (double v = std::ceil(ymin_ / ys) * ys; v <= ymax_; v += ys)
	{
		const double y = py(v);
		a += "<line x1=\"" + num(plot_l_) + "\" y1=\"" + num(y) + "\" x2=\"" +
		     num(plot_l_ + plot_w_) + "\" y2=\"" + num(y) +
		     "\" stroke=\"#e4e4e4\"/>\n";
		a += "<text x=\"" + num(plot_l_ - 6) + "\" y=\"" + num(y + 4) +
		     "\" text-anchor=\"end\">" + tickLabel(v, ys) + "</text>\n";
	}
	a += "<text x=\"" + num(plot_l_ + plot_w_ / 2) + "\" y=\"" +
	     num(plot_t_ + plot_h_ + 38) + "\" text-anchor=\"middle\">" +
	     svgEscape(xlabel) + "</text>\n";
	const double ylx = left_ + 16, yly = plot_t_ + plot_h_ / 2;
	a += "<text x=\"" + num(ylx) + "\" y=\"" + num(yly) +
	     "\" text-anchor=\"middle\" transform=\"rotate(-90 " + num(ylx) + " " +
	     num(yly) + ")\">" + svgEscape(ylabel) + "</text>\n";
	a += "<text x=\"" + num(plot_l_ + plot_w_ / 2) + "\" y=\"" +
	     num(top_ + 22) + "\" text-anchor=\"middle\" font-weight=\"bold\">" +
	     svgEscape(title) + "</text>\n";
	// Grid first so the data is drawn over it.
	body_ = a + body_;
}

void SvgPanel::legend(
    const std::vector<std::pair<std::string, SvgStyle>>& entries)
{
	double y = plot_t_ + 14;
	const double x = plot_l_ + 10;
	body_ += "<rect x=\"" + num(x - 4) + "\" y=\"" + num(plot_t_ + 3) +
	         "\" width=\"190\" height=\"" + num(18.0 * entries.size() + 4) +
	         "\" fill=\"white\" opacity=\"0.85\"/>\n";
	for (const auto& [label, s] : entries)
	{
		SvgStyle ls = s;
		if (ls.width_px < 2) ls.width_px = 2;
		body_ += "<line x1=\"" + num(x) + "\" y1=\"" + num(y - 4) + "\" x2=\"" +
		         num(x + 24) + "\" y2=\"" + num(y - 4) + "\"" + styleAttrs(ls) +
		         "/>\n";
		body_ += "<text x=\"" + num(x + 30) + "\" y=\"" + num(y) + "\">" +
		         svgEscape(label) + "</text>\n";
		y += 18;
	}
}

void writeSvgDocument(std::ostream& os, double width_px, double height_px,
                      const std::vector<const SvgPanel*>& panels,
                      const std::string& title)
{
	os << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
	   << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << num(width_px)
	   << "\" height=\"" << num(height_px) << "\" viewBox=\"0 0 "
	   << num(width_px) << " " << num(height_px)
	   << "\" font-family=\"sans-serif\" font-size=\"12\">\n"
	   << "<title>" << svgEscape(title) << "</title>\n"
	   << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
	for (const auto* p : panels) os << p->body();
	os << "</svg>\n";
}

}  // namespace forest_slam::eval
