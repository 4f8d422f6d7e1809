#include <forest_slam/core/memory.h>

#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <cstdio>

namespace forest_slam::core
{
double currentRssMb()
{
	// statm: size resident shared ... in pages.
	std::FILE* f = std::fopen("/proc/self/statm", "r");
	if (!f) return 0;
	unsigned long size = 0, resident = 0;
	const int n = std::fscanf(f, "%lu %lu", &size, &resident);
	std::fclose(f);
	if (n != 2) return 0;
	return resident * static_cast<double>(sysconf(_SC_PAGESIZE)) /
	       (1024.0 * 1024.0);
}

double peakRssMb()
{
	rusage u{};
	getrusage(RUSAGE_SELF, &u);
	return u.ru_maxrss / 1024.0;  // Linux: kilobytes
}

double processCpuSeconds()
{
	rusage u{};
	getrusage(RUSAGE_SELF, &u);
	return u.ru_utime.tv_sec + u.ru_stime.tv_sec +
	       1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

double threadCpuSeconds()
{
	timespec t{};
	if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t) != 0) return 0;
	return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

}  // namespace forest_slam::core
