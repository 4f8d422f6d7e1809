#include <forest_slam/odometry/map_inserter.h>

namespace forest_slam::odometry
{
MapInserter::MapInserter(map::CForestMap& map, size_t max_pending)
    : map_(map), worker_(max_pending, "fs-mapinsert", true)
{
}

MapInserter::~MapInserter() = default;

void MapInserter::push(std::vector<Eigen::Vector3f> edges,
                       std::vector<Eigen::Vector3f> planar,
                       const Eigen::Isometry3d& sensor_to_map)
{
	worker_.push([this, e = std::move(edges), p = std::move(planar),
	              sensor_to_map] { map_.insertFeatures(e, p, sensor_to_map); });
}

void MapInserter::run(std::function<void(map::CForestMap&)> job)
{
	worker_.push([this, j = std::move(job)] { j(map_); });
}

}  // namespace forest_slam::odometry
