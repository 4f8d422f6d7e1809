#include <forest_slam/ingest/wire.h>

#include <cstring>

namespace forest_slam::ingest
{
WireReader::WireReader(const uint8_t* data, size_t size, Wire wire)
    : data_(data), size_(size), wire_(wire)
{
	if (wire_ != Wire::Cdr) return;
	need(4, "CDR encapsulation header");
	// Byte 1 is the representation id: 0x00 CDR_BE, 0x01 CDR_LE. The
	// parameter-list and XCDR2 encodings are not what rosbag2 writes for
	// plain ROS messages.
	if (data_[0] != 0x00 || (data_[1] != 0x00 && data_[1] != 0x01))
		throw DecodeError("unsupported CDR encapsulation 0x" +
		                  std::to_string(static_cast<int>(data_[0])) + "/" +
		                  std::to_string(static_cast<int>(data_[1])) +
		                  " (expected plain CDR little or big endian)");
	swap_ = data_[1] == 0x00;
	pos_ = origin_ = 4;
}

void WireReader::need(size_t n, const char* what) const
{
	if (n > size_ - pos_)
		throw DecodeError(std::string("message truncated reading ") + what +
		                  ": needs " + std::to_string(n) + " bytes at offset " +
		                  std::to_string(pos_) + ", message has " +
		                  std::to_string(size_));
}

void WireReader::align(size_t n)
{
	if (wire_ != Wire::Cdr || n <= 1) return;
	const size_t rel = pos_ - origin_;
	const size_t pad = (n - rel % n) % n;
	need(pad, "alignment padding");
	pos_ += pad;
}

template <typename T>
T WireReader::primitive(const char* what)
{
	align(sizeof(T));
	need(sizeof(T), what);
	uint8_t buf[sizeof(T)];
	std::memcpy(buf, data_ + pos_, sizeof(T));
	if (swap_)
		for (size_t i = 0; i < sizeof(T) / 2; i++)
			std::swap(buf[i], buf[sizeof(T) - 1 - i]);
	T v;
	std::memcpy(&v, buf, sizeof(T));
	pos_ += sizeof(T);
	return v;
}

uint8_t WireReader::u8()
{
	return primitive<uint8_t>("uint8");
}
uint16_t WireReader::u16()
{
	return primitive<uint16_t>("uint16");
}
uint32_t WireReader::u32()
{
	return primitive<uint32_t>("uint32");
}
uint64_t WireReader::u64()
{
	return primitive<uint64_t>("uint64");
}
float WireReader::f32()
{
	return primitive<float>("float32");
}
double WireReader::f64()
{
	return primitive<double>("float64");
}

std::string WireReader::string()
{
	const uint32_t n = u32();
	need(n, "string");
	size_t len = n;
	// CDR counts the terminating NUL; ROS 1 does not store one.
	if (wire_ == Wire::Cdr && len > 0 && data_[pos_ + len - 1] == '\0') len--;
	std::string s(reinterpret_cast<const char*>(data_ + pos_), len);
	pos_ += n;
	return s;
}

int64_t WireReader::timeNs()
{
	int64_t sec;
	if (wire_ == Wire::Ros1)
		sec = u32();
	else
		sec = i32();
	const uint32_t nsec = u32();
	return sec * 1000000000LL + nsec;
}

uint32_t WireReader::arrayLength(size_t min_element_bytes)
{
	const uint32_t n = u32();
	if (min_element_bytes > 0 && n > remaining() / min_element_bytes)
		throw DecodeError("array length " + std::to_string(n) + " at offset " +
		                  std::to_string(pos_ - 4) + " exceeds the " +
		                  std::to_string(remaining()) +
		                  " bytes left in the message");
	return n;
}

const uint8_t* WireReader::bytes(size_t n)
{
	need(n, "byte array");
	const uint8_t* p = data_ + pos_;
	pos_ += n;
	return p;
}

}  // namespace forest_slam::ingest
