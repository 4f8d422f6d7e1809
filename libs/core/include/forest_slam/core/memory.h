#pragma once
// Memory accounting: the process's resident set (from the kernel) and
// estimates of what the big containers hold, so a run can say where its
// memory goes (run_summary.json "memory", doc/performance.md). Estimates
// count element storage and, for node-based hash maps, one node and one
// bucket pointer per element; allocator overhead is not counted, so the sum
// of the parts stays below the RSS.
#include <cstddef>
#include <unordered_map>
#include <vector>

namespace forest_slam::core
{
/** Resident set size of this process now [MB]; 0 if /proc is unreadable. */
double currentRssMb();
/** Peak resident set size of this process so far [MB] (getrusage). */
double peakRssMb();
/** CPU time of this process so far, user + system, all threads [s]. */
double processCpuSeconds();
/** CPU time of the calling thread so far, user + system [s]. */
double threadCpuSeconds();

template <class T, class A>
size_t vectorBytes(const std::vector<T, A>& v)
{
	return v.capacity() * sizeof(T);
}

/** A std::unordered_map node holds the value and the next pointer (libstdc++
 * also caches the hash when the hash function is not trivially fast). */
template <class K, class V, class H, class E, class A>
size_t hashMapBytes(const std::unordered_map<K, V, H, E, A>& m)
{
	constexpr size_t kNode =
	    sizeof(void*) + sizeof(std::pair<const K, V>) + sizeof(size_t);
	return m.bucket_count() * sizeof(void*) + m.size() * kNode;
}

inline double toMb(size_t bytes)
{
	return bytes / (1024.0 * 1024.0);
}

}  // namespace forest_slam::core
