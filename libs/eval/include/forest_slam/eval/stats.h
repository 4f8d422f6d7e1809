#pragma once
// Summary statistics shared by every metric so that "std" and "rmse" mean
// the same thing in every table and JSON block.
#include <cstddef>
#include <limits>
#include <vector>

namespace forest_slam::eval
{
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct SummaryStats
{
	size_t count = 0;
	double mean = kNaN;
	double std = kNaN;  ///< sample standard deviation (N-1); 0 when N == 1
	double min = kNaN;
	double max = kNaN;
	double median = kNaN;
	double rmse = kNaN;  ///< sqrt(mean(v^2)): the RMS of the values
};

/** All fields NaN (count 0) for an empty input. */
SummaryStats summarize(const std::vector<double>& values);

}  // namespace forest_slam::eval
