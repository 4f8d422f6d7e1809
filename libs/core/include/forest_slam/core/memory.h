#pragma once
// Memory accounting: the process's resident set (from the kernel) and
// estimates of what the big containers hold, so a run can say where its
// memory goes (run_summary.json "memory", doc/performance.md). Estimates
// count element storage and, for node-based hash maps, one node and one
// bucket pointer per element; allocator overhead is not counted, so the sum
// of the parts stays below the RSS.
#include <cstddef>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace forest_slam::core
{
/** Resident set size of this process now [MB]; 0 if /proc is unreadable. */
double currentRssMb();
/** What glibc's malloc holds now, over all its arenas (mallinfo2) [MB]:
 * `in_use` is handed out to the program (blocks of the heap and the
 * blocks mapped apart), `free` is freed but kept by malloc (free lists,
 * holes between used blocks, the top of each arena), resident or not:
 * releaseFreedHeap() hands whole free pages back to the kernel and they
 * still count here. Resident memory that no container accounts for is
 * mostly one of these two. */
struct HeapUse
{
	double in_use_mb = 0, free_mb = 0, mapped_mb = 0;
	int arenas = 0;  ///< malloc's arenas (one per thread that allocated, up to
	                 ///< 8 x cores)
};
HeapUse heapUse();
/** Gives the whole free pages of malloc's arenas back to the system
 * (malloc_trim): glibc keeps freed heap otherwise, and across threads it
 * piles up (robot run, 3 laps: ~150 MB of the RSS after 900 s of data).
 * Returns the RSS released [MB]. Takes 10-30 ms for a ~1 GB heap, during
 * which other threads' malloc calls wait for their arena. */
double releaseFreedHeap();
/** Free bytes malloc may keep at the top of one of its heaps before free()
 * hands them back to the system (mallopt M_TRIM_THRESHOLD). While scans
 * are mapped: kHeapKeptWhileMapping, so that the buffers a worker frees
 * and allocates again every scan or keyframe do not fault their pages in
 * each time (the mapping loop gives the freed heap back every 30 s of
 * data instead, releaseFreedHeap). For the end-of-run steps, which free
 * their buffers once: glibc's default, kHeapKeptAtTheEnd. Returns false if
 * malloc refused. */
bool setHeapKeptFree(size_t bytes);
inline constexpr size_t kHeapKeptWhileMapping = size_t(128) << 20;
inline constexpr size_t kHeapKeptAtTheEnd = size_t(128) << 10;
/** Peak resident set size of this process so far [MB] (getrusage). */
double peakRssMb();
/** CPU time of this process so far, user + system, all threads [s]. */
double processCpuSeconds();
/** CPU time of the calling thread so far, user + system [s]. */
double threadCpuSeconds();
/** CPU time so far of this process's live threads, summed by thread name
 * (/proc/self/task/<tid>/comm and stat; the workers are named fs-...),
 * in order of first appearance [s]. Empty if /proc is unreadable. */
std::vector<std::pair<std::string, double>> threadCpuByName();
/** How far runInBackground lowers a worker's priority (nice increment,
 * capped at 19): to the lowest for recorded input, where nothing else
 * needs the cores and the odometry's threads should have them; by 5 for
 * live input, where other programs on the robot's computer share the
 * cores and a starved worker would hold the scans back. */
constexpr int kBackgroundNiceRecorded = 19, kBackgroundNiceLive = 5;
/** Sets the increment for the workers started from now on (default
 * kBackgroundNiceRecorded). */
void setBackgroundNice(int increment);
int backgroundNice();
/** Lowers the calling thread's priority by backgroundNice() (at most to
 * nice 19): for the workers whose results nobody waits for while their
 * queues have room (the CForestMap's insertion, the output collector, the
 * back-end), so that when both cores are wanted the odometry's threads,
 * on which every scan waits, get them first. Returns false if the system
 * refused (then nothing changed). */
bool runInBackground();

/** Whether glibc's malloc of this process advises transparent huge pages
 * (the tunable glibc.malloc.hugetlb, read at process start). */
bool heapOnHugePages();
/** The environment variable that turns useHugePages() off ("0"). */
inline constexpr const char* kHugePagesEnv = "FOREST_SLAM_HUGE_PAGES";
/** Re-executes this program (/proc/self/exe, same `argv`) once with
 * GLIBC_TUNABLES=glibc.malloc.hugetlb=1 added, so that malloc advises
 * transparent huge pages for its blocks (the kernel's usual THP mode,
 * "madvise", gives them only to memory advised so). Large blocks that are
 * mapped and unmapped over and over (stem-band columns read back, detection
 * buffers) then fault 2 MB at a time instead of 4 kB: on a 2-core VM the
 * handheld run's page faults went 3.9 M -> 1.6 M, its CPU 316 -> 281 s.
 * Returns (does nothing) when the tunable is set already (by the user or
 * the first execution), when FOREST_SLAM_HUGE_PAGES=0, when the kernel's
 * THP mode is "never", or when exec fails. Call first thing in main(). */
void useHugePages(char** argv);

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
