#include "fuzz_targets.h"

#include <forest_slam/core/config.h>
#include <forest_slam/pipeline/mapping_config.h>

#include <string>

namespace forest_slam::fuzz
{
int fuzzIni(const uint8_t* data, size_t size)
{
	const std::string text(reinterpret_cast<const char*>(data), size);
	try
	{
		auto cfg = core::TrackedConfig::fromText(text, "fuzz.ini");
		const auto mc = pipeline::MappingConfig::load(cfg);
		// A loaded configuration dumps to an INI that loads again.
		auto again = core::TrackedConfig::fromText(mc.dump(), "dump.ini");
		pipeline::MappingConfig::load(again);
	}
	catch (const core::ConfigError&)
	{
	}
	return 0;
}
}  // namespace forest_slam::fuzz

#ifdef FOREST_SLAM_LIBFUZZER
FS_FUZZ_MAIN(fuzzIni)
#endif
