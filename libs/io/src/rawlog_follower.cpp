#include <forest_slam/io/rawlog_follower.h>
#include <forest_slam/io/rawlog_reader.h>

#include <mrpt/io/CMemoryStream.h>
#include <mrpt/serialization/CArchive.h>
#include <zlib.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <thread>

namespace forest_slam::io
{
namespace
{
using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t)
{
	return std::chrono::duration<double>(Clock::now() - t).count();
}
}  // namespace

RawlogFollower::RawlogFollower(const std::string& path, FollowOptions opts)
    : path_(path), opts_(std::move(opts))
{
	// gzopen decides gzip vs plain from the first two bytes: wait for them.
	const auto t0 = Clock::now();
	std::error_code ec;
	while (!(std::filesystem::is_regular_file(path, ec) &&
	         std::filesystem::file_size(path, ec) >= 2))
	{
		if ((opts_.should_stop && opts_.should_stop()) ||
		    secondsSince(t0) > opts_.idle_timeout_s)
			throw std::runtime_error("--follow: '" + path +
			                         "' did not appear (or stayed empty) for " +
			                         std::to_string(opts_.idle_timeout_s) +
			                         " s");
		std::this_thread::sleep_for(
		    std::chrono::duration<double>(opts_.poll_period_s));
	}
	{
		std::ifstream f(path, std::ios::binary);
		unsigned char magic[2] = {0, 0};
		f.read(reinterpret_cast<char*>(magic), 2);
		gzip_ = magic[0] == 0x1f && magic[1] == 0x8b;
	}
	gz_ = gzopen(path.c_str(), "rb");
	if (!gz_)
		throw std::runtime_error("cannot open '" + path +
		                         "': " + std::strerror(errno));
}

RawlogFollower::~RawlogFollower()
{
	if (gz_) gzclose(static_cast<gzFile>(gz_));
}

size_t RawlogFollower::readAvailable()
{
	auto* g = static_cast<gzFile>(gz_);
	gzclearerr(g);  // past EOF: let gzread look at the file again
	size_t total = 0;
	constexpr unsigned kChunk = 1u << 18;
	for (;;)
	{
		const size_t old = buf_.size();
		buf_.resize(old + kChunk);
		const int n = gzread(g, buf_.data() + old, kChunk);
		buf_.resize(old + static_cast<size_t>(std::max(n, 0)));
		if (n > 0) total += static_cast<size_t>(n);
		if (n < static_cast<int>(kChunk)) break;
	}
	int err = Z_OK;
	const char* msg = gzerror(g, &err);
	// Z_BUF_ERROR: the gzip stream ends mid-block, i.e. is still being written.
	if (err != Z_OK && err != Z_BUF_ERROR)
		throw RawlogError(path_ + ": compressed stream damaged near record " +
		                      std::to_string(records_) + ": " +
		                      (msg ? msg : "?"),
		                  path_, records_, bytesConsumed());
	return total;
}

bool RawlogFollower::parseOne()
{
	if (pos_ >= buf_.size()) return false;
	mrpt::io::CMemoryStream mem;
	mem.assignMemoryNotOwn(buf_.data() + pos_, buf_.size() - pos_);
	mrpt::serialization::CSerializable::Ptr obj;
	try
	{
		auto arch = mrpt::serialization::archiveFrom(mem);
		obj = arch.ReadObject();
	}
	catch (const std::exception& e)
	{
		last_parse_error_ = e.what();
		return false;  // incomplete (most likely) or corrupt
	}
	pos_ += static_cast<size_t>(mem.getPosition());
	records_++;
	appendRecordObservations(obj, pending_);
	return true;
}

void RawlogFollower::compact()
{
	if (pos_ < (1u << 20) || pos_ < buf_.size() / 2) return;
	buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(pos_));
	base_offset_ += pos_;
	pos_ = 0;
}

mrpt::obs::CObservation::Ptr RawlogFollower::next()
{
	auto last_growth = Clock::now();
	while (pending_.empty())
	{
		if (done_) return nullptr;
		if (parseOne())
		{
			compact();
			continue;
		}
		if (readAvailable() > 0)
		{
			last_growth = Clock::now();
			continue;
		}
		if (opts_.should_stop && opts_.should_stop())
		{
			done_ = stopped_ = true;
			return nullptr;
		}
		if (secondsSince(last_growth) > opts_.idle_timeout_s)
		{
			done_ = true;
			if (pos_ == buf_.size()) return nullptr;  // ended at a record
			std::string what = last_parse_error_;
			if (what.size() > 300) what = what.substr(0, 300) + "...";
			throw RawlogError(
			    path_ + ": record " + std::to_string(records_) +
			        " starting at byte " + std::to_string(bytesConsumed()) +
			        " is incomplete or corrupt and the file stopped growing " +
			        std::to_string(opts_.idle_timeout_s) + " s ago (" +
			        std::to_string(buf_.size() - pos_) +
			        " bytes left over): " + what,
			    path_, records_, bytesConsumed());
		}
		std::this_thread::sleep_for(
		    std::chrono::duration<double>(opts_.poll_period_s));
	}
	auto o = pending_.front();
	pending_.pop_front();
	observations_++;
	return o;
}

}  // namespace forest_slam::io
