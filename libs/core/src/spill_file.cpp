#include <forest_slam/core/spill_file.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

namespace forest_slam::core
{
namespace
{
std::string errorText()
{
	return std::strerror(errno);
}
}  // namespace

SpillFile::SpillFile(const std::string& dir) : dir_(dir)
{
	if (dir_.empty())
	{
		const char* t = std::getenv("TMPDIR");
		dir_ = t && *t ? t : "/tmp";
	}
#ifdef O_TMPFILE
	fd_ = ::open(dir_.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
#endif
	if (fd_ < 0)  // file systems without O_TMPFILE: create, then unlink
	{
		std::string name = dir_ + "/forest-slam-spill.XXXXXX";
		fd_ = ::mkostemp(name.data(), O_CLOEXEC);
		if (fd_ >= 0) ::unlink(name.c_str());
	}
	if (fd_ < 0)
		throw std::runtime_error("cannot create a spill file in '" + dir_ +
		                         "': " + errorText());
}

SpillFile::~SpillFile()
{
	if (fd_ >= 0) ::close(fd_);
}

uint64_t SpillFile::append(const void* data, size_t bytes)
{
	const uint64_t at = end_;
	writeAt(at, data, bytes);
	end_ += bytes;
	return at;
}

void SpillFile::overwrite(uint64_t offset, const void* data, size_t bytes)
{
	if (offset + bytes > end_)
		throw std::logic_error("SpillFile::overwrite beyond the end");
	writeAt(offset, data, bytes);
}

void SpillFile::discard(uint64_t offset, size_t bytes)
{
	if (offset + bytes > end_)
		throw std::logic_error("SpillFile::discard beyond the end");
	discarded_ += bytes;
#ifdef FALLOC_FL_PUNCH_HOLE
	// File systems without hole punching keep the blocks: only the space
	// is lost, not data, so the error is not worth stopping a run.
	(void)::fallocate(fd_, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE,
	                  static_cast<off_t>(offset), static_cast<off_t>(bytes));
#endif
}

uint64_t SpillFile::allocatedBytes() const
{
	struct stat st;
	if (::fstat(fd_, &st) != 0) return end_;
	return static_cast<uint64_t>(st.st_blocks) * 512;
}

void SpillFile::writeAt(uint64_t at, const void* data, size_t bytes)
{
	const char* p = static_cast<const char*>(data);
	size_t done = 0;
	while (done < bytes)
	{
		const ssize_t n = ::pwrite(fd_, p + done, bytes - done,
		                           static_cast<off_t>(at + done));
		if (n < 0 && errno == EINTR) continue;
		if (n <= 0)
			throw std::runtime_error(
			    "cannot write the spill file in '" + dir_ +
			    "': " + errorText() +
			    " (long runs keep far map parts there: free space there or "
			    "choose another folder: $TMPDIR, [outputs] spill_dir)");
		done += static_cast<size_t>(n);
	}
}

void SpillFile::read(uint64_t offset, void* data, size_t bytes) const
{
	if (offset + bytes > end_)
		throw std::logic_error("SpillFile::read beyond the end");
	char* p = static_cast<char*>(data);
	size_t done = 0;
	while (done < bytes)
	{
		const ssize_t n = ::pread(fd_, p + done, bytes - done,
		                          static_cast<off_t>(offset + done));
		if (n < 0 && errno == EINTR) continue;
		if (n <= 0)
			throw std::runtime_error("cannot read the spill file in '" + dir_ +
			                         "': " + errorText());
		done += static_cast<size_t>(n);
	}
}

}  // namespace forest_slam::core
