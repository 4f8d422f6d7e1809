#pragma once
// keyframes.simplemap: the keyframes as an MRPT CSimpleMap (one
// CSensoryFrame with a CObservationPointCloud per keyframe, at the lidar
// pose), so MRPT tools (e.g. RawLogViewer, sm2mm, mrpt-sm-cli) open it.
#include <forest_slam/outputs/run_collector.h>

#include <mrpt/maps/CSimpleMap.h>

#include <string>

namespace forest_slam::outputs
{
/** Observations labelled `sensor_label`, timestamped with the keyframe time;
 * points in the sensor frame, the pose PDF a CPose3DPDFGaussian with zero
 * covariance (no uncertainty estimate yet). */
mrpt::maps::CSimpleMap toSimpleMap(const Keyframes& keyframes,
                                   const std::string& sensor_label = "lidar");

/** CSimpleMap::saveToFile (gzip MRPT archive) through a temp file + rename. */
void writeSimpleMap(const std::string& path, const mrpt::maps::CSimpleMap& sm);
/** Same file from keyframe poses and clouds read one at a time through
 * `cloud_of(i)` (RunCollector::keyframeCloud): memory for one keyframe, not
 * the whole map; the bytes are those saveToFile writes for the same map. */
void writeSimpleMap(const std::string& path, const Keyframes& keyframes,
                    const KeyframeCloudLoader& cloud_of,
                    const std::string& sensor_label = "lidar");

}  // namespace forest_slam::outputs
