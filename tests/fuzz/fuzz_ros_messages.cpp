#include "fuzz_targets.h"

#include <forest_slam/ingest/messages.h>
#include <forest_slam/ingest/pointcloud2.h>
#include <forest_slam/ingest/velodyne.h>

#include <stdexcept>
#include <vector>

namespace forest_slam::fuzz
{
namespace
{
void cloud(const uint8_t* d, size_t n, ingest::Wire w, uint8_t selector)
{
	const auto msg = ingest::decodePointCloud2(d, n, w);
	ingest::CloudLayoutOptions o;
	// The named-field paths as well as the automatic search.
	if (selector & 0x10) o.time_encoding = "relative_ns";
	if (selector & 0x20) o.ring_field = "none";
	if (selector & 0x40) o.intensity_field = "none";
	const auto layout = ingest::analyzeCloudLayout(msg, o);
	std::vector<ingest::CloudPoint> pts;
	ingest::extractCloudPoints(msg, layout, pts);
	(void)layout.describe();
}

void velodyne(const uint8_t* d, size_t n, ingest::Wire w)
{
	const auto msg = ingest::decodeVelodyneScan(d, n, w);
	std::vector<const uint8_t*> packets;
	for (const auto& p : msg.packets) packets.push_back(p.data.data());
	std::vector<ingest::VelodynePoint> out;
	for (const char* model : {"VLP16", "HDL32"})
	{
		try
		{
			ingest::decodeVelodynePackets(
			    packets, ingest::defaultVelodyneCalibration(model), {}, out);
		}
		catch (const std::runtime_error&)  // documented: unsupported model
		{
		}
	}
}
}  // namespace

int fuzzRosMessages(const uint8_t* data, size_t size)
{
	if (size < 1) return 0;
	const uint8_t sel = data[0];
	const auto wire = (sel & 1) ? ingest::Wire::Cdr : ingest::Wire::Ros1;
	const uint8_t* d = data + 1;
	const size_t n = size - 1;
	try
	{
		switch ((sel >> 1) % 5)
		{
			case 0:
				cloud(d, n, wire, sel);
				break;
			case 1:
				ingest::decodeImu(d, n, wire);
				break;
			case 2:
				ingest::decodeNavSatFix(d, n, wire);
				break;
			case 3:
				ingest::decodeTfMessage(d, n, wire);
				break;
			case 4:
				velodyne(d, n, wire);
				break;
		}
	}
	catch (const ingest::DecodeError&)
	{
	}
	return 0;
}
}  // namespace forest_slam::fuzz

#ifdef FOREST_SLAM_LIBFUZZER
FS_FUZZ_MAIN(fuzzRosMessages)
#endif
