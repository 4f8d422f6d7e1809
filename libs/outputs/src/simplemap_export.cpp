#include <forest_slam/core/atomic_file.h>
#include <forest_slam/outputs/simplemap_export.h>

#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose3DPDFGaussian.h>
#include <mrpt/system/datetime.h>

#include <stdexcept>

namespace forest_slam::outputs
{
mrpt::maps::CSimpleMap toSimpleMap(const Keyframes& keyframes,
                                   const std::string& sensor_label)
{
	mrpt::maps::CSimpleMap sm;
	for (const auto& kf : keyframes)
	{
		auto pts = mrpt::maps::CSimplePointsMap::Create();
		pts->reserve(kf.points.size());
		for (const auto& p : kf.points) pts->insertPoint(p.x(), p.y(), p.z());
		auto obs = mrpt::obs::CObservationPointCloud::Create();
		obs->sensorLabel = sensor_label;
		obs->timestamp = mrpt::Clock::fromDouble(kf.t_s);
		obs->pointcloud = pts;
		auto sf = mrpt::obs::CSensoryFrame::Create();
		sf->insert(obs);
		auto pdf = mrpt::poses::CPose3DPDFGaussian::Create();
		pdf->mean = mrpt::poses::CPose3D(
		    mrpt::math::CMatrixDouble44(kf.sensor_pose.matrix()));
		sm.insert(pdf, sf);
	}
	return sm;
}

void writeSimpleMap(const std::string& path, const mrpt::maps::CSimpleMap& sm)
{
	if (!sm.saveToFile(core::tempPathFor(path)))
		throw std::runtime_error("cannot write simple map '" + path + "'");
	core::commitTempFile(path);
}

}  // namespace forest_slam::outputs
