#pragma once
// Splits a loop over [0, n) into chunks taken from a shared counter by the
// calling thread and up to threads - 1 helper threads. The helpers belong to
// the calling thread: created on its first parallel loop, asleep between
// loops, joined when it exits. Starting std::threads for every loop (three
// registration searches and a clustering per scan) did not pay: by the time
// a new thread ran, the caller had taken nearly every chunk (perf, handheld
// run: the started threads did 1 % of the k-NN matching, a woken helper
// about half).
#include <cstddef>
#include <functional>

namespace forest_slam::core
{
/** fn(begin, end, worker) over chunks of [0, n); worker is 0 on the calling
 * thread, 1..threads-1 on helpers (an index for per-worker scratch). Each
 * chunk runs exactly once, on some worker; results written per index are
 * the same for any thread count. An exception thrown by fn stops the
 * remaining chunks and is rethrown here once every worker has stopped.
 * threads <= 1, or n no larger than one chunk, runs inline. */
void parallelRanges(size_t n, int threads, size_t chunk,
                    const std::function<void(size_t, size_t, int)>& fn);

/** fn(i) for every i in [0, n), as parallelRanges. */
template <class F>
void parallelFor(size_t n, int threads, size_t chunk, const F& fn)
{
	parallelRanges(n, threads, chunk,
	               [&fn](size_t b, size_t e, int)
	               {
		               for (size_t i = b; i < e; i++) fn(i);
	               });
}

}  // namespace forest_slam::core
