#pragma once
// The last of a sorted list of times at or before a query time, in constant
// time: the back-end's corrections look up the scan of every stem-band
// voxel and dense-map point (tens of millions), and a bisection per lookup
// was a sixth of a tree-layer correction's CPU (perf, robot run).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace forest_slam::core
{
class TimeIndex
{
   public:
	/** `t`: non-decreasing (scan start times). */
	explicit TimeIndex(std::vector<double> t) : t_(std::move(t))
	{
		if (t_.size() < 2 || !(t_.back() > t_.front())) return;
		// Buckets of the mean spacing, each holding the answer at its start.
		step_ = (t_.back() - t_.front()) / double(t_.size() - 1);
		first_.resize(t_.size() + 1);
		for (size_t b = 0; b < first_.size(); b++)
			first_[b] = bisect(t_.front() + double(b) * step_);
	}

	/** Index of the last time <= ts; 0 if none (ts before the first or
	 * the list empty), the last index for NaN (as std::upper_bound). */
	size_t at(double ts) const
	{
		if (first_.empty() || std::isnan(ts) || !(ts >= t_.front()) ||
		    ts >= t_.back())
			return bisect(ts);
		size_t i = first_[std::min(first_.size() - 1,
		                           size_t((ts - t_.front()) / step_))];
		// The bucket's start may round to either side of ts.
		while (i > 0 && t_[i] > ts) i--;
		while (i + 1 < t_.size() && t_[i + 1] <= ts) i++;
		return i;
	}
	/** The same by bisection (the definition). */
	size_t bisect(double ts) const
	{
		const size_t u =
		    size_t(std::upper_bound(t_.begin(), t_.end(), ts) - t_.begin());
		return u > 0 ? u - 1 : 0;
	}
	const std::vector<double>& times() const { return t_; }

   private:
	std::vector<double> t_;
	double step_ = 0;
	std::vector<size_t> first_;
};

}  // namespace forest_slam::core
