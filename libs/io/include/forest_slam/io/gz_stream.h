#pragma once
// zlib-backed MRPT stream that reads gzip or plain files transparently and
// reports the *compressed* byte offset, which is what progress (% of file)
// and error messages ("damaged at byte N") need.
#include <mrpt/io/CStream.h>

#include <cstdint>
#include <string>

namespace forest_slam::io
{
class GzInputStream : public mrpt::io::CStream
{
   public:
	/** Throws std::runtime_error naming the path if it cannot be opened. */
	explicit GzInputStream(const std::string& path);
	~GzInputStream() override;
	GzInputStream(const GzInputStream&) = delete;
	GzInputStream& operator=(const GzInputStream&) = delete;

	size_t Read(void* buf, size_t count) override;
	size_t Write(const void*, size_t) override;
	uint64_t Seek(int64_t off, mrpt::io::CStream::TSeekOrigin o) override;
	uint64_t getTotalBytesCount() const override;  ///< file size on disk
	uint64_t getPosition() const override;	///< uncompressed position
	std::string getStreamDescription() const override { return path_; }

	uint64_t compressedOffset() const;	///< bytes of the file consumed
	/** True if no more bytes can be read (does not consume). */
	bool atEnd();
	/** zlib's last error text, if the stream is damaged. */
	std::string errorText() const;
	const std::string& path() const { return path_; }
	/** Re-checks the file size (for files still being written). */
	void refreshSize();

   private:
	std::string path_;
	void* gz_ = nullptr;  // gzFile
	uint64_t file_size_ = 0;
};

}  // namespace forest_slam::io
