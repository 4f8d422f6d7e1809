#include <forest_slam/core/atomic_file.h>
#include <forest_slam/io/rawlog_writer.h>

#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/serialization/CArchive.h>

#include <cstdio>
#include <stdexcept>

namespace forest_slam::io
{
RawlogWriter::RawlogWriter(const std::string& path, int compress_level)
	: path_(path), out_(std::make_unique<mrpt::io::CFileGZOutputStream>())
{
	if (!out_->open(core::tempPathFor(path), compress_level))
		throw std::runtime_error(
			"cannot create rawlog '" + core::tempPathFor(path) + "'");
}

RawlogWriter::~RawlogWriter()
{
	if (!closed_)
	{
		out_.reset();
		std::remove(core::tempPathFor(path_).c_str());
	}
}

void RawlogWriter::write(const mrpt::obs::CObservation& obs)
{
	auto arch = mrpt::serialization::archiveFrom(*out_);
	arch << obs;
	count_++;
}

void RawlogWriter::close()
{
	if (closed_) return;
	out_->close();
	core::commitTempFile(path_);
	closed_ = true;
}

}  // namespace forest_slam::io
