#pragma once
// An unnamed scratch file for data a long run no longer needs in memory
// (dense-map tiles far from the sensor, keyframe clouds, finished tree-layer
// columns): blobs are appended and read back by offset. The file has no
// name (O_TMPFILE, or created and unlinked at once), so the kernel frees it
// when the process ends, kill -9 included: nothing to clean up, nothing
// left behind.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace forest_slam::core
{
class SpillFile
{
   public:
	/** `dir` empty: $TMPDIR, else /tmp. Throws std::runtime_error naming
	 * the folder when no file can be created there. */
	explicit SpillFile(const std::string& dir = "");
	~SpillFile();
	SpillFile(const SpillFile&) = delete;
	SpillFile& operator=(const SpillFile&) = delete;

	/** Appends `bytes` bytes; returns their offset. Throws on I/O errors
	 * (disk full) naming the folder. */
	uint64_t append(const void* data, size_t bytes);
	void read(uint64_t offset, void* data, size_t bytes) const;
	/** Sets `bytes` bytes aside at the end, to be filled with overwrite();
	 * returns their offset. */
	uint64_t reserve(size_t bytes)
	{
		const uint64_t at = end_;
		end_ += bytes;
		return at;
	}
	/** Replaces bytes already written (same length, in place). */
	void overwrite(uint64_t offset, const void* data, size_t bytes);
	/** The blob at [offset, offset + bytes) is not read again: its disk
	 * blocks go back to the file system (a hole is punched; the file keeps
	 * its length, offsets stay valid). A blob written again after each
	 * revisit otherwise left every old copy on disk: the 58-minute run's
	 * tree layer filled a 50 GB disk. */
	void discard(uint64_t offset, size_t bytes);

	template <class T>
	uint64_t appendVector(const std::vector<T>& v)
	{
		return append(v.data(), v.size() * sizeof(T));
	}
	template <class T>
	void overwriteVector(uint64_t offset, const std::vector<T>& v)
	{
		overwrite(offset, v.data(), v.size() * sizeof(T));
	}
	template <class T>
	void readVector(uint64_t offset, size_t n, std::vector<T>& v) const
	{
		v.resize(n);
		read(offset, v.data(), n * sizeof(T));
	}

	/** Bytes written so far (the file's length only grows). */
	uint64_t size() const { return end_; }
	/** Bytes written and not discarded. */
	uint64_t liveBytes() const { return end_ - discarded_; }
	/** Disk space the file takes now (its allocated blocks). */
	uint64_t allocatedBytes() const;
	const std::string& dir() const { return dir_; }

   private:
	void writeAt(uint64_t at, const void* data, size_t bytes);
	std::string dir_;
	int fd_ = -1;
	uint64_t end_ = 0;
	uint64_t discarded_ = 0;
};

}  // namespace forest_slam::core
