#include <forest_slam/core/memory.h>

#include <dirent.h>
#include <malloc.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>

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

HeapUse heapUse()
{
	const struct mallinfo2 m = mallinfo2();
	HeapUse h;
	h.in_use_mb = toMb(m.uordblks + m.hblkhd);
	h.free_mb = toMb(m.fordblks);
	h.mapped_mb = toMb(m.hblkhd);
	// malloc_info's XML is the only place glibc names its arenas.
	char* buf = nullptr;
	size_t len = 0;
	if (std::FILE* f = open_memstream(&buf, &len))
	{
		if (malloc_info(0, f) == 0)
		{
			std::fflush(f);
			for (const char* p = buf; p && (p = std::strstr(p, "<heap nr="));
			     p++)
				h.arenas++;
		}
		std::fclose(f);
		std::free(buf);
	}
	return h;
}

double releaseFreedHeap()
{
	const double before = currentRssMb();
	malloc_trim(0);
	return before - currentRssMb();
}

bool setHeapKeptFree(size_t bytes)
{
	return mallopt(M_TRIM_THRESHOLD, int(std::min<size_t>(bytes, INT32_MAX))) ==
	       1;
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

namespace
{
std::atomic<int> g_background_nice{kBackgroundNiceRecorded};
}  // namespace

void setBackgroundNice(int increment)
{
	g_background_nice = std::clamp(increment, 0, 39);
}

int backgroundNice()
{
	return g_background_nice;
}

bool runInBackground()
{
	// Linux gives each thread its own nice value (PRIO_PROCESS with a
	// thread id); raising it needs no privilege.
	const auto tid = static_cast<id_t>(syscall(SYS_gettid));
	errno = 0;
	const int now = getpriority(PRIO_PROCESS, tid);
	if (errno != 0) return false;
	// Recorded input: the lowest priority (19), not a step below the
	// caller (+5, before 2026-12-07). At +5 the scheduler still gave these
	// workers a quarter of a core the odometry wanted; at 19 they run in
	// the gaps the odometry's threads leave, and when their queues fill
	// the odometry waits and they catch up (interleaved pairs: robot 3000
	// scans 65.4 -> 68.3 scans/s, handheld 2000 scans 52.5 -> 59.0, the
	// same CPU; doc/performance.md).
	const int target = std::min(19, now + backgroundNice());
	if (target <= now) return true;
	return setpriority(PRIO_PROCESS, tid, target) == 0;
}

std::vector<std::pair<std::string, double>> threadCpuByName()
{
	std::vector<std::pair<std::string, double>> out;
	DIR* d = opendir("/proc/self/task");
	if (!d) return out;
	const double tick = 1.0 / double(sysconf(_SC_CLK_TCK));
	while (const dirent* e = readdir(d))
	{
		if (e->d_name[0] == '.') continue;
		const std::string task = std::string("/proc/self/task/") + e->d_name;
		std::ifstream comm(task + "/comm"), stat(task + "/stat");
		std::string name, line;
		if (!std::getline(comm, name) || !std::getline(stat, line))
			continue;  // the thread ended meanwhile
		// Fields after the ")" closing the name: state is field 3, utime
		// and stime are fields 14 and 15.
		const size_t close = line.rfind(')');
		if (close == std::string::npos) continue;
		unsigned long utime = 0, stime = 0;
		if (std::sscanf(line.c_str() + close + 1,
		                " %*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %lu %lu",
		                &utime, &stime) != 2)
			continue;
		const double s = double(utime + stime) * tick;
		auto it = out.begin();
		while (it != out.end() && it->first != name) ++it;
		if (it == out.end())
			out.emplace_back(name, s);
		else
			it->second += s;
	}
	closedir(d);
	return out;
}

double threadCpuSeconds()
{
	timespec t{};
	if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t) != 0) return 0;
	return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

namespace
{
/** The value of glibc.malloc.hugetlb in GLIBC_TUNABLES, or "" if unset. */
std::string hugetlbTunable()
{
	const char* t = std::getenv("GLIBC_TUNABLES");
	if (!t) return "";
	const std::string s(t), key = "glibc.malloc.hugetlb=";
	const size_t at = s.find(key);
	if (at == std::string::npos) return "";
	const size_t from = at + key.size();
	return s.substr(from, s.find(':', from) - from);
}
}  // namespace

bool heapOnHugePages()
{
	const std::string v = hugetlbTunable();
	return !v.empty() && v != "0";
}

void useHugePages(char** argv)
{
	if (std::getenv("GLIBC_TUNABLES") &&
	    std::strstr(std::getenv("GLIBC_TUNABLES"), "glibc.malloc.hugetlb"))
		return;  // set already: by the user, or this is the re-execution
	const char* off = std::getenv(kHugePagesEnv);
	if (off && std::strcmp(off, "0") == 0) return;
	std::ifstream mode("/sys/kernel/mm/transparent_hugepage/enabled");
	std::string line;
	if (!mode || !std::getline(mode, line) ||
	    line.find("[never]") != std::string::npos)
		return;
	const char* old = std::getenv("GLIBC_TUNABLES");
	const std::string value = old && *old
	                              ? std::string(old) + ":glibc.malloc.hugetlb=1"
	                              : std::string("glibc.malloc.hugetlb=1");
	if (setenv("GLIBC_TUNABLES", value.c_str(), 1) != 0) return;
	execv("/proc/self/exe", argv);
	// exec failed (no /proc, say): the run goes on with 4 kB pages, and the
	// environment as it was.
	if (old)
		setenv("GLIBC_TUNABLES", old, 1);
	else
		unsetenv("GLIBC_TUNABLES");
}

}  // namespace forest_slam::core
