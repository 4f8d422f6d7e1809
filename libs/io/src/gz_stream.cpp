#include <forest_slam/io/gz_stream.h>

#include <zlib.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace forest_slam::io
{
GzInputStream::GzInputStream(const std::string& path) : path_(path)
{
	std::error_code ec;
	if (!std::filesystem::is_regular_file(path, ec))
		throw std::runtime_error("cannot open '" + path + "': no such file");
	file_size_ = std::filesystem::file_size(path, ec);
	gz_ = gzopen(path.c_str(), "rb");
	if (!gz_)
		throw std::runtime_error(
			"cannot open '" + path + "': " + std::strerror(errno));
	gzbuffer(static_cast<gzFile>(gz_), 1 << 17);
}

GzInputStream::~GzInputStream()
{
	if (gz_) gzclose(static_cast<gzFile>(gz_));
}

size_t GzInputStream::Read(void* buf, size_t count)
{
	size_t done = 0;
	auto* p = static_cast<unsigned char*>(buf);
	while (done < count)
	{
		const unsigned chunk =
			static_cast<unsigned>(std::min<size_t>(count - done, 1u << 30));
		const int n = gzread(static_cast<gzFile>(gz_), p + done, chunk);
		if (n <= 0) break;
		done += static_cast<size_t>(n);
	}
	return done;
}

size_t GzInputStream::Write(const void*, size_t)
{
	throw std::runtime_error("GzInputStream is read-only: " + path_);
}

uint64_t GzInputStream::Seek(int64_t off, mrpt::io::CStream::TSeekOrigin o)
{
	int whence = SEEK_SET;
	if (o == sFromCurrent) whence = SEEK_CUR;
	if (o == sFromEnd)
		throw std::runtime_error("GzInputStream cannot seek from end: " + path_);
	const auto r = gzseek(static_cast<gzFile>(gz_), off, whence);
	if (r < 0) throw std::runtime_error("seek failed in '" + path_ + "'");
	return static_cast<uint64_t>(r);
}

uint64_t GzInputStream::getTotalBytesCount() const { return file_size_; }

uint64_t GzInputStream::getPosition() const
{
	return static_cast<uint64_t>(gztell(static_cast<gzFile>(gz_)));
}

uint64_t GzInputStream::compressedOffset() const
{
	const auto off = gzoffset(static_cast<gzFile>(gz_));
	return off < 0 ? 0 : static_cast<uint64_t>(off);
}

bool GzInputStream::atEnd()
{
	auto* g = static_cast<gzFile>(gz_);
	const int c = gzgetc(g);
	if (c < 0)
	{
		gzclearerr(g);	// allow reading again if the file grows (--follow)
		return true;
	}
	gzungetc(c, g);
	return false;
}

std::string GzInputStream::errorText() const
{
	int err = 0;
	const char* msg = gzerror(static_cast<gzFile>(gz_), &err);
	return (err == Z_OK || !msg) ? std::string() : std::string(msg);
}

void GzInputStream::refreshSize()
{
	std::error_code ec;
	const auto s = std::filesystem::file_size(path_, ec);
	if (!ec) file_size_ = s;
}

}  // namespace forest_slam::io
