#pragma once
// floor and lrint without the libm call: x86-64's baseline (no SSE4.1) has
// no rounding instruction, so -O2 calls libm for std::floor and std::lrint.
// For per-point work (lattice cells, stem-band voxels) the calls cost more
// than the arithmetic around them.
#include <cmath>
#include <cstdint>
#if defined(__SSE__)
#include <xmmintrin.h>
#endif

namespace forest_slam::core
{
/** std::floor as an integer: the same result for |v| < 2^62. */
inline int64_t floorToInt(double v)
{
	const int64_t i = static_cast<int64_t>(v);
	return i - static_cast<int64_t>(static_cast<double>(i) > v);
}
inline int64_t floorToInt(float v)
{
	const int64_t i = static_cast<int64_t>(v);
	return i - static_cast<int64_t>(static_cast<float>(i) > v);
}

/** std::lrint: the SSE conversion rounds as the current rounding mode
 * does, as lrint. */
inline long roundToLong(float v)
{
#if defined(__SSE__)
	return _mm_cvtss_si32(_mm_set_ss(v));
#else
	return std::lrint(v);
#endif
}
}  // namespace forest_slam::core
