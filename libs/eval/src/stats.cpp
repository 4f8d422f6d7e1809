#include <forest_slam/eval/stats.h>

#include <algorithm>
#include <cmath>

namespace forest_slam::eval
{
SummaryStats summarize(const std::vector<double>& values)
{
	SummaryStats s;
	s.count = values.size();
	if (values.empty()) return s;
	double sum = 0, sum_sq = 0;
	for (double v : values)
	{
		sum += v;
		sum_sq += v * v;
	}
	const double n = static_cast<double>(values.size());
	s.mean = sum / n;
	s.rmse = std::sqrt(sum_sq / n);
	double dev_sq = 0;
	for (double v : values) dev_sq += (v - s.mean) * (v - s.mean);
	s.std = values.size() > 1 ? std::sqrt(dev_sq / (n - 1)) : 0.0;
	const auto [mn, mx] = std::minmax_element(values.begin(), values.end());
	s.min = *mn;
	s.max = *mx;
	std::vector<double> sorted = values;
	std::sort(sorted.begin(), sorted.end());
	const size_t h = sorted.size() / 2;
	s.median =
	    sorted.size() % 2 ? sorted[h] : 0.5 * (sorted[h - 1] + sorted[h]);
	return s;
}

}  // namespace forest_slam::eval
