#pragma once
// Writes a gzip rawlog atomically: observations go to a temporary file that
// is renamed over the target by close(); a crash leaves the old file intact.
#include <mrpt/obs/CObservation.h>

#include <memory>
#include <string>

namespace mrpt::io
{
class CFileGZOutputStream;
}

namespace forest_slam::io
{
class RawlogWriter
{
   public:
	/** compress_level 0..9 (1 is fast and still ~3x smaller). */
	explicit RawlogWriter(const std::string& path, int compress_level = 1);
	/** Discards the temporary file if close() was not called. */
	~RawlogWriter();
	void write(const mrpt::obs::CObservation& obs);
	/** Flushes and moves the file into place. */
	void close();
	uint64_t count() const { return count_; }

   private:
	std::string path_;
	std::unique_ptr<mrpt::io::CFileGZOutputStream> out_;
	uint64_t count_ = 0;
	bool closed_ = false;
};

}  // namespace forest_slam::io
