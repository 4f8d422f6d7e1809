#include <forest_slam/core/atomic_file.h>
#include <forest_slam/core/log.h>
#include <forest_slam/outputs/simplemap_export.h>

#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose3DPDFGaussian.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/system/datetime.h>

#include <cstring>
#include <stdexcept>

namespace forest_slam::outputs
{
namespace
{
struct Entry
{
	mrpt::poses::CPose3DPDFGaussian::Ptr pose;
	mrpt::obs::CSensoryFrame::Ptr sf;
};

Entry makeEntry(const KeyframeCloud& kf,
                const std::vector<Eigen::Vector3f>& points,
                const std::string& sensor_label)
{
	auto pts = mrpt::maps::CSimplePointsMap::Create();
	pts->reserve(points.size());
	for (const auto& p : points) pts->insertPoint(p.x(), p.y(), p.z());
	auto obs = mrpt::obs::CObservationPointCloud::Create();
	obs->sensorLabel = sensor_label;
	obs->timestamp = mrpt::Clock::fromDouble(kf.t_s);
	obs->pointcloud = pts;
	Entry e;
	e.sf = mrpt::obs::CSensoryFrame::Create();
	e.sf->insert(obs);
	e.pose = mrpt::poses::CPose3DPDFGaussian::Create();
	e.pose->mean = mrpt::poses::CPose3D(
	    mrpt::math::CMatrixDouble44(kf.sensor_pose.matrix()));
	return e;
}

template <class F>
std::string archiveBytes(F&& write)
{
	mrpt::io::CMemoryStream ms;
	auto arch = mrpt::serialization::archiveFrom(ms);
	write(arch);
	return std::string(static_cast<const char*>(ms.getRawBufferData()),
	                   ms.getTotalBytesCount());
}

std::string u32(uint32_t v)
{
	std::string s(4, '\0');
	std::memcpy(s.data(), &v, 4);  // MRPT archives are little-endian
	return s;
}

/** The bytes MRPT writes for a CSimpleMap around its entries: archive(map)
 * = head + uint32 count + entries + tail. Learnt from this MRPT itself
 * (an empty map and a one-entry map) and checked, so a streamed file is
 * byte for byte what CSimpleMap::saveToFile would write; false if the
 * layout is not that (another MRPT version): then the map is built in
 * memory instead. */
bool simpleMapFraming(const Entry& sample, std::string& head, std::string& tail)
{
	mrpt::maps::CSimpleMap sm0, sm1;
	sm1.insert(sample.pose, sample.sf);
	const std::string b0 = archiveBytes([&](auto& a) { a << sm0; });
	const std::string b1 = archiveBytes([&](auto& a) { a << sm1; });
	const std::string e =
	    archiveBytes([&](auto& a) { a << *sample.pose << *sample.sf; });
	for (size_t k = 0; k + 4 <= b0.size(); k++)
	{
		if (b0.compare(k, 4, u32(0)) != 0) continue;
		const std::string h = b0.substr(0, k), t = b0.substr(k + 4);
		if (b1 == h + u32(1) + e + t)
		{
			head = h;
			tail = t;
			return true;
		}
	}
	return false;
}
}  // namespace

mrpt::maps::CSimpleMap toSimpleMap(const Keyframes& keyframes,
                                   const std::string& sensor_label)
{
	mrpt::maps::CSimpleMap sm;
	for (const auto& kf : keyframes)
	{
		const Entry e = makeEntry(kf, kf.points, sensor_label);
		sm.insert(e.pose, e.sf);
	}
	return sm;
}

void writeSimpleMap(const std::string& path, const mrpt::maps::CSimpleMap& sm)
{
	if (!sm.saveToFile(core::tempPathFor(path)))
		throw std::runtime_error("cannot write simple map '" + path + "'");
	core::commitTempFile(path);
}

void writeSimpleMap(const std::string& path, const Keyframes& keyframes,
                    const KeyframeCloudLoader& cloud_of,
                    const std::string& sensor_label)
{
	std::string head, tail;
	if (keyframes.empty() ||
	    !simpleMapFraming(makeEntry(keyframes[0], cloud_of(0), sensor_label),
	                      head, tail))
	{
		if (!keyframes.empty())
			FS_LOG_WARN(
			    "keyframes.simplemap: this MRPT frames CSimpleMap "
			    "differently; building it in memory");
		mrpt::maps::CSimpleMap sm;
		for (size_t i = 0; i < keyframes.size(); i++)
		{
			const Entry e = makeEntry(keyframes[i], cloud_of(i), sensor_label);
			sm.insert(e.pose, e.sf);
		}
		writeSimpleMap(path, sm);
		return;
	}
	// One keyframe in memory at a time. CSimpleMap::saveToFile writes a
	// gzip stream of the archive; so does this.
	{
		mrpt::io::CFileGZOutputStream out;
		if (!out.open(core::tempPathFor(path)))
			throw std::runtime_error("cannot write simple map '" + path + "'");
		out.Write(head.data(), head.size());
		const std::string n = u32(static_cast<uint32_t>(keyframes.size()));
		out.Write(n.data(), n.size());
		auto arch = mrpt::serialization::archiveFrom(out);
		for (size_t i = 0; i < keyframes.size(); i++)
		{
			const Entry e = makeEntry(keyframes[i], cloud_of(i), sensor_label);
			arch << *e.pose << *e.sf;
		}
		out.Write(tail.data(), tail.size());
		out.close();
	}
	core::commitTempFile(path);
}

}  // namespace forest_slam::outputs
