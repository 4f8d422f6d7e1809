#pragma once
// Bounds-checked readers of serialized ROS messages. ROS 1 serialization is
// packed little-endian with uint32 length prefixes; ROS 2 bags store CDR:
// a 4-byte encapsulation header, then primitives aligned to their own size
// (relative to the end of that header) and strings carrying a trailing NUL.
// One reader with a `Wire` switch lets each message decoder be written once.
#include <cstdint>
#include <stdexcept>
#include <string>

namespace forest_slam::ingest
{
/** A message that does not match the layout of its declared type. */
class DecodeError : public std::runtime_error
{
   public:
	using std::runtime_error::runtime_error;
};

enum class Wire
{
	Ros1,
	Cdr
};

class WireReader
{
   public:
	/** For CDR, reads and checks the encapsulation header (CDR_LE/CDR_BE;
	 * PL_CDR and XCDR2 are rejected with DecodeError). */
	WireReader(const uint8_t* data, size_t size, Wire wire);

	Wire wire() const { return wire_; }
	size_t offset() const { return pos_; }
	size_t size() const { return size_; }
	size_t remaining() const { return size_ - pos_; }

	uint8_t u8();
	int8_t i8() { return static_cast<int8_t>(u8()); }
	uint16_t u16();
	uint32_t u32();
	int32_t i32() { return static_cast<int32_t>(u32()); }
	uint64_t u64();
	float f32();
	double f64();
	bool boolean() { return u8() != 0; }
	std::string string();
	/** ROS 1 time (uint32 sec, uint32 nsec) or ROS 2 builtin_interfaces/Time
	 * (int32 sec, uint32 nanosec), as nanoseconds since the epoch. */
	int64_t timeNs();
	/** Length prefix of a variable-size array; checked against the bytes
	 * left assuming each element needs at least `min_element_bytes`. */
	uint32_t arrayLength(size_t min_element_bytes);
	/** Pointer to `n` raw bytes (uint8[] payloads), advancing past them. */
	const uint8_t* bytes(size_t n);
	/** Aligns for a primitive of `n` bytes (no-op for ROS 1). */
	void align(size_t n);

   private:
	const uint8_t* data_;
	size_t size_;
	size_t pos_ = 0;
	size_t origin_ = 0;  ///< CDR alignment origin (after encapsulation)
	Wire wire_;
	bool swap_ = false;  ///< big-endian CDR on a little-endian host
	void need(size_t n, const char* what) const;
	template <typename T>
	T primitive(const char* what);
};

}  // namespace forest_slam::ingest
