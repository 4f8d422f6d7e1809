#include <forest_slam/online/raw_recorder.h>

#include <mrpt/io/CMemoryStream.h>
#include <mrpt/serialization/CArchive.h>
#include <zlib.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace forest_slam::online
{
RawRecorder::RawRecorder(const std::string& path, int compress_level,
                         double flush_period_s)
    : path_(path), gzip_(compress_level > 0), flush_period_s_(flush_period_s)
{
	std::error_code ec;
	if (std::filesystem::exists(path, ec))
		throw std::runtime_error(
		    "'" + path +
		    "' exists: a recording is never overwritten (choose another --out "
		    "or move it away)");
	if (gzip_)
		file_ = gzopen(path.c_str(),
		               ("wb" + std::to_string(compress_level)).c_str());
	else
		file_ = std::fopen(path.c_str(), "wb");
	if (!file_)
		throw std::runtime_error("cannot create '" + path +
		                         "': " + std::strerror(errno));
	thread_ = std::thread([this] { run(); });
}

RawRecorder::~RawRecorder()
{
	try
	{
		close();
	}
	catch (const std::exception&)
	{
		// close() already reported through the pipeline's error path
	}
}

void RawRecorder::record(const mrpt::obs::CObservation::Ptr& obs)
{
	{
		std::lock_guard<std::mutex> lk(mu_);
		if (closing_) return;
		queue_.push_back(obs);
	}
	cv_.notify_one();
}

uint64_t RawRecorder::recorded() const
{
	std::lock_guard<std::mutex> lk(mu_);
	return recorded_;
}
uint64_t RawRecorder::bytes() const
{
	std::lock_guard<std::mutex> lk(mu_);
	return bytes_;
}
size_t RawRecorder::queued() const
{
	std::lock_guard<std::mutex> lk(mu_);
	return queue_.size();
}

void RawRecorder::writeBytes(const void* data, size_t n)
{
	bool ok;
	if (gzip_)
		ok = gzwrite(static_cast<gzFile>(file_), data,
		             static_cast<unsigned>(n)) == static_cast<int>(n);
	else
		ok = std::fwrite(data, 1, n, static_cast<FILE*>(file_)) == n;
	if (!ok)
		throw std::runtime_error("writing '" + path_ +
		                         "' failed: " + std::strerror(errno));
}

void RawRecorder::flush()
{
	// Z_SYNC_FLUSH ends the deflate block so that a follower can read it.
	if (gzip_ ? gzflush(static_cast<gzFile>(file_), Z_SYNC_FLUSH) != Z_OK
	          : std::fflush(static_cast<FILE*>(file_)) != 0)
		throw std::runtime_error("flushing '" + path_ +
		                         "' failed: " + std::strerror(errno));
}

void RawRecorder::run()
{
	using Clock = std::chrono::steady_clock;
	const auto period = std::chrono::duration_cast<Clock::duration>(
	    std::chrono::duration<double>(flush_period_s_));
	auto last_flush = Clock::now();
	bool dirty = false;
	mrpt::io::CMemoryStream mem;
	std::unique_lock<std::mutex> lk(mu_);
	for (;;)
	{
		cv_.wait_for(lk, period, [&] { return closing_ || !queue_.empty(); });
		while (!queue_.empty())
		{
			auto obs = queue_.front();
			queue_.pop_front();
			lk.unlock();
			std::string err;
			size_t n = 0;
			try
			{
				// One record is serialized whole, then written with one call.
				mem.clear();
				auto arch = mrpt::serialization::archiveFrom(mem);
				arch << *obs;
				n = static_cast<size_t>(mem.getTotalBytesCount());
				writeBytes(mem.getRawBufferData(), n);
				dirty = true;
			}
			catch (const std::exception& e)
			{
				err = e.what();
			}
			lk.lock();
			if (!err.empty())
			{
				if (error_.empty()) error_ = err;
				continue;
			}
			recorded_++;
			bytes_ += n;
		}
		if (dirty && (closing_ || Clock::now() - last_flush >= period))
		{
			lk.unlock();
			std::string err;
			try
			{
				flush();
			}
			catch (const std::exception& e)
			{
				err = e.what();
			}
			lk.lock();
			if (!err.empty() && error_.empty()) error_ = err;
			dirty = false;
			last_flush = Clock::now();
		}
		if (closing_ && queue_.empty()) return;
	}
}

void RawRecorder::close()
{
	{
		std::lock_guard<std::mutex> lk(mu_);
		if (closed_) return;
		closing_ = true;
	}
	cv_.notify_one();
	if (thread_.joinable()) thread_.join();
	int rc = 0;
	if (gzip_)
		rc = gzclose(static_cast<gzFile>(file_)) == Z_OK ? 0 : -1;
	else
		rc = std::fclose(static_cast<FILE*>(file_));
	file_ = nullptr;
	closed_ = true;
	// Nothing recorded (a sensor failed to start): leave no empty file that
	// would block the next run into the same folder.
	if (recorded_ == 0 && rc == 0 && error_.empty()) std::remove(path_.c_str());
	if (rc != 0 && error_.empty())
		error_ = "closing '" + path_ + "' failed: " + std::strerror(errno);
	if (!error_.empty()) throw std::runtime_error(error_);
}

}  // namespace forest_slam::online
