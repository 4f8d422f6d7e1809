#include <forest_slam/io/rawlog_reader.h>

#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/serialization/CArchive.h>

namespace forest_slam::io
{
void appendRecordObservations(
	const mrpt::serialization::CSerializable::Ptr& record,
	std::deque<mrpt::obs::CObservation::Ptr>& out)
{
	if (auto obs = std::dynamic_pointer_cast<mrpt::obs::CObservation>(record))
		out.push_back(obs);
	else if (auto sf = std::dynamic_pointer_cast<mrpt::obs::CSensoryFrame>(record))
		for (const auto& o : *sf) out.push_back(o);
	// CActionCollection and other objects carry nothing we use.
}

RawlogReader::RawlogReader(const std::string& path)
	: path_(path), in_(std::make_unique<GzInputStream>(path))
{
}

RawlogReader::~RawlogReader() = default;

mrpt::obs::CObservation::Ptr RawlogReader::next()
{
	while (pending_.empty())
	{
		if (done_) return nullptr;
		if (in_->atEnd())
		{
			done_ = true;
			if (const auto e = in_->errorText(); !e.empty())
			{
				damaged_ = true;
				throw RawlogError(
					path_ + ": compressed stream damaged after record " +
						std::to_string(records_) + " (byte " +
						std::to_string(in_->compressedOffset()) + "): " + e,
					path_, records_, in_->compressedOffset());
			}
			return nullptr;
		}
		const uint64_t offset = in_->compressedOffset();
		mrpt::serialization::CSerializable::Ptr obj;
		try
		{
			auto arch = mrpt::serialization::archiveFrom(*in_);
			obj = arch.ReadObject();
		}
		catch (const std::exception& e)
		{
			done_ = true;
			damaged_ = true;
			std::string what = e.what();
			if (what.size() > 300) what = what.substr(0, 300) + "...";
			throw RawlogError(
				path_ + ": record " + std::to_string(records_) +
					" starting near byte " + std::to_string(offset) +
					" is truncated or corrupt: " + what,
				path_, records_, offset);
		}
		records_++;
		appendRecordObservations(obj, pending_);
	}
	auto o = pending_.front();
	pending_.pop_front();
	observations_++;
	return o;
}

double RawlogReader::fractionRead() const
{
	const auto total = in_->getTotalBytesCount();
	if (total == 0) return 1.0;
	return std::min(1.0, static_cast<double>(in_->compressedOffset()) / total);
}

}  // namespace forest_slam::io
