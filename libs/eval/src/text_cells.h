#pragma once
// printf-style helpers shared by the text tables of the trajectory and tree
// reports (internal to libs/eval).
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <string>

namespace forest_slam::eval::detail
{
inline std::string fmt(const char* f, ...)
{
	char buf[512];
	va_list ap;
	va_start(ap, f);
	std::vsnprintf(buf, sizeof(buf), f, ap);
	va_end(ap);
	return buf;
}

/** Fixed-width number, "-" for NaN/inf. */
inline std::string cell(double v, int width, int decimals)
{
	if (!std::isfinite(v)) return fmt("%*s", width, "-");
	// Values that round to zero print as 0, not "-0.00".
	if (std::abs(v) < 0.5 * std::pow(10.0, -decimals)) v = 0;
	return fmt("%*.*f", width, decimals, v);
}

}  // namespace forest_slam::eval::detail
