#include "fuzz_targets.h"

#include <forest_slam/io/las.h>

#include <cmath>
#include <stdexcept>
#include <vector>

namespace forest_slam::fuzz
{
int fuzzLas(const uint8_t* data, size_t size)
{
	const std::vector<char> bytes(data, data + size);
	for (const bool partial : {false, true})
	{
		try
		{
			const auto c = io::parseLas(bytes, "fuzz.las", partial);
			// Every attribute has one entry per point (or none).
			if (c.intensity.size() != c.size() ||
			    c.classification.size() != c.size() ||
			    (!c.gps_time_s.empty() && c.gps_time_s.size() != c.size()))
				throw std::logic_error("LAS attribute sizes differ");
			if (!partial && !c.damage.empty())
				throw std::logic_error("damage reported without partial");
		}
		catch (const io::CloudFileError&)
		{
		}
	}
	return 0;
}
}  // namespace forest_slam::fuzz

#ifdef FOREST_SLAM_LIBFUZZER
FS_FUZZ_MAIN(fuzzLas)
#endif
