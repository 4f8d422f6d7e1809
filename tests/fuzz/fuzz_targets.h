#pragma once
// Entry functions of the fuzz targets. Each takes arbitrary bytes and must
// either succeed or throw the reader's documented error type; anything else
// (a crash, a sanitizer report, another exception) is a bug. The libFuzzer
// binaries (make fuzz, build-fuzz) and the corpus replay test (ctest, the
// normal build) call the same functions.
#include <cstddef>
#include <cstdint>

namespace forest_slam::fuzz
{
/** io::parseLas, whole and partial. */
int fuzzLas(const uint8_t* data, size_t size);
/** ROS 1 / ROS 2 (CDR) message decoders; byte 0 picks wire and type, the
 * rest is the payload. PointCloud2 goes on through the layout analysis and
 * point extraction, VelodyneScan through the packet decoder. */
int fuzzRosMessages(const uint8_t* data, size_t size);
/** The mapping INI loader (TrackedConfig + MappingConfig::load). */
int fuzzIni(const uint8_t* data, size_t size);
}  // namespace forest_slam::fuzz

// The libFuzzer entry point of one binary: FS_FUZZ_MAIN(fuzzLas).
#define FS_FUZZ_MAIN(fn)                                                    \
	extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) \
	{                                                                       \
		return ::forest_slam::fuzz::fn(data, size);                         \
	}
