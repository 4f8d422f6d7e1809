#pragma once
// Records every observation to DIR/raw.rawlog as it arrives, on its own
// thread so that neither a slow disk nor a slow pipeline stalls the sensor
// threads. The file is written in place (not through a temporary file): it
// is a journal that must survive a crash up to its last flush and that
// `forest-slam map --follow` can read while it grows. A plain rawlog (the
// default) can be re-processed offline exactly as the online run saw it.
#include <mrpt/obs/CObservation.h>

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <thread>

namespace forest_slam::online
{
class RawRecorder
{
   public:
	/** Throws std::runtime_error naming the path if it exists (a previous
	 * recording is never overwritten) or cannot be created.
	 * compress_level 0 = plain rawlog, 1..9 gzip. */
	RawRecorder(const std::string& path, int compress_level,
	            double flush_period_s);
	~RawRecorder();  ///< close()
	RawRecorder(const RawRecorder&) = delete;
	RawRecorder& operator=(const RawRecorder&) = delete;

	/** Thread-safe, never blocks on I/O. */
	void record(const mrpt::obs::CObservation::Ptr& obs);
	/** Writes everything queued, flushes and closes (removes the file if
	 * nothing was recorded). Rethrows a write error
	 * (disk full...) seen by the writer thread. */
	void close();

	uint64_t recorded() const;  ///< observations on disk
	uint64_t bytes() const;
	size_t queued() const;
	const std::string& path() const { return path_; }

   private:
	std::string path_;
	void* file_ = nullptr;  // FILE* (plain) or gzFile
	bool gzip_;
	double flush_period_s_;
	mutable std::mutex mu_;
	std::condition_variable cv_;
	std::deque<mrpt::obs::CObservation::Ptr> queue_;
	bool closing_ = false, closed_ = false;
	uint64_t recorded_ = 0, bytes_ = 0;
	std::string error_;
	std::thread thread_;
	void run();
	void writeBytes(const void* data, size_t n);
	void flush();
};

}  // namespace forest_slam::online
