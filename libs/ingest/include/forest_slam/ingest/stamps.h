#pragma once
// ROS stamps are UNIX nanoseconds; MRPT's TTimeStamp counts 100 ns ticks
// since 1601. Integer conversion keeps the 100 ns resolution that
// mrpt::Clock::fromDouble() loses for present-day dates.
#include <mrpt/core/Clock.h>

#include <cstdint>

namespace forest_slam::ingest
{
constexpr int64_t kUnixEpochIn100ns = 116444736000000000LL;

inline mrpt::Clock::time_point fromUnixNs(int64_t ns)
{
	// Round to the nearest tick (floor division for negative values is not
	// needed: bags start after 1970).
	return mrpt::Clock::time_point(
	    mrpt::Clock::duration((ns + 50) / 100 + kUnixEpochIn100ns));
}

inline int64_t toUnixNs(mrpt::Clock::time_point t)
{
	return (static_cast<int64_t>(t.time_since_epoch().count()) -
	        kUnixEpochIn100ns) *
	       100;
}

}  // namespace forest_slam::ingest
