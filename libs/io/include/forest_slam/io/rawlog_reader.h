#pragma once
// Streams a rawlog (gzip or plain) one observation at a time, never loading
// the file whole: hour-long rawlogs are gigabytes. Sensory frames are
// flattened into their observations; actions are skipped.
#include <forest_slam/io/gz_stream.h>
#include <mrpt/obs/CObservation.h>

#include <deque>
#include <memory>
#include <stdexcept>
#include <string>

namespace forest_slam::io
{
/** Damage in a rawlog: names the file, the record index and byte offset. */
class RawlogError : public std::runtime_error
{
   public:
	RawlogError(const std::string& msg, std::string file, uint64_t record,
				uint64_t byte_offset)
		: std::runtime_error(msg),
		  file(std::move(file)),
		  record(record),
		  byte_offset(byte_offset)
	{
	}
	std::string file;
	uint64_t record;
	uint64_t byte_offset;  ///< compressed offset where the damage starts
};

/** Appends the observations one rawlog record holds (an observation, or
 * those of a CSensoryFrame); actions and other objects hold none we use. */
void appendRecordObservations(
	const mrpt::serialization::CSerializable::Ptr& record,
	std::deque<mrpt::obs::CObservation::Ptr>& out);

class RawlogReader
{
   public:
	/** Throws std::runtime_error if the file cannot be opened. */
	explicit RawlogReader(const std::string& path);
	~RawlogReader();

	/** Next observation, or nullptr at a clean end of file. Throws
	 * RawlogError if the record is truncated or corrupt; the reader is then
	 * done (further calls return nullptr). */
	mrpt::obs::CObservation::Ptr next();

	/** Fraction of the file consumed, [0,1] (compressed bytes). */
	double fractionRead() const;
	uint64_t recordsRead() const { return records_; }
	uint64_t observationsRead() const { return observations_; }
	const std::string& path() const { return path_; }
	/** True once next() threw RawlogError. */
	bool damaged() const { return damaged_; }

   private:
	std::string path_;
	std::unique_ptr<GzInputStream> in_;
	std::deque<mrpt::obs::CObservation::Ptr> pending_;
	uint64_t records_ = 0, observations_ = 0;
	bool done_ = false, damaged_ = false;
};

}  // namespace forest_slam::io
