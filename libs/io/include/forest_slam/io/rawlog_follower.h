#pragma once
// Reads a rawlog that another process is still writing (rawlog-grabber,
// `forest-slam online`, a copy in progress): end of file means "wait for
// more", a record cut in the middle is re-read from its start once more
// bytes arrived. Plain rawlogs are followed record by record; gzip ones too
// (zlib reads a stream that ends mid-block), but a gzip writer only makes
// data visible in compressed blocks, so they lag behind.
#include <mrpt/obs/CObservation.h>

#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace forest_slam::io
{
struct FollowOptions
{
	/** The writer is considered done when the file did not grow for this
	 * long (also the wait for the file to appear). */
	double idle_timeout_s = 10.0;
	double poll_period_s = 0.05;
	/** Polled while waiting: true ends the run at once (SIGINT). */
	std::function<bool()> should_stop;
};

class RawlogFollower
{
   public:
	/** Waits up to idle_timeout_s for `path` to appear; throws
	 * std::runtime_error naming it if it does not. */
	RawlogFollower(const std::string& path, FollowOptions opts);
	~RawlogFollower();
	RawlogFollower(const RawlogFollower&) = delete;
	RawlogFollower& operator=(const RawlogFollower&) = delete;

	/** Next observation; waits while the file grows. nullptr once the file
	 * stopped growing for idle_timeout_s at a record boundary, or when
	 * should_stop() said so. Throws RawlogError (rawlog_reader.h) if the
	 * file stopped growing in the middle of a record, or the record cannot
	 * be decoded however many bytes follow it. */
	mrpt::obs::CObservation::Ptr next();

	uint64_t recordsRead() const { return records_; }
	uint64_t observationsRead() const { return observations_; }
	/** Bytes of (decompressed) rawlog consumed so far. */
	uint64_t bytesConsumed() const { return base_offset_ + pos_; }
	bool gzip() const { return gzip_; }
	/** True if next() returned nullptr because should_stop() said so. */
	bool stopped() const { return stopped_; }
	const std::string& path() const { return path_; }

   private:
	std::string path_;
	FollowOptions opts_;
	void* gz_ = nullptr;  // gzFile: reads plain files transparently
	bool gzip_ = false, done_ = false, stopped_ = false;
	std::vector<uint8_t> buf_;  ///< decompressed bytes not yet consumed
	size_t pos_ = 0;            ///< parse position in buf_
	uint64_t base_offset_ = 0;  ///< stream offset of buf_[0]
	uint64_t records_ = 0, observations_ = 0;
	std::deque<mrpt::obs::CObservation::Ptr> pending_;
	std::string last_parse_error_;

	/** Appends whatever the writer added since the last call; returns the
	 * number of bytes read. */
	size_t readAvailable();
	/** One record from buf_ if it is complete; false if more bytes are
	 * needed (or the record is corrupt: only growth can tell). */
	bool parseOne();
	void compact();
};

}  // namespace forest_slam::io
