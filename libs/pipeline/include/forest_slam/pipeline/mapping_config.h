#pragma once
// Every module's options for one mapping run, loaded from one INI file. An
// INI key that no module reads is an error (core::TrackedConfig).
#include <forest_slam/core/config.h>
#include <forest_slam/loop/loop_options.h>
#include <forest_slam/map/forest_map.h>
#include <forest_slam/pipeline/pipeline_options.h>
#include <forest_slam/odometry/lidar_odometry.h>
#include <forest_slam/outputs/output_options.h>
#include <forest_slam/trees/tree_options.h>

#include <ostream>
#include <string>

namespace forest_slam::pipeline
{
struct MappingConfig
{
	PipelineOptions pipeline;		  ///< [pipeline]
	map::ForestMapOptions forest_map;  ///< [forest_map]
	/** [odometry] [registration] [ground] [cluster] [features] */
	odometry::OdometryConfig odometry;
	loop::LoopOptions loop;            ///< [loop]
	trees::TreeOptions trees;		   ///< [trees]
	outputs::OutputOptions outputs;	 ///< [outputs]
	outputs::GeoOptions georeference;  ///< [georeference]

	/** Loads all sections and rejects unknown keys; throws core::ConfigError
	 * naming file, section and key. */
	static MappingConfig load(core::TrackedConfig& cfg);
	static MappingConfig loadFile(const std::string& path);

	/** The effective configuration as a valid INI text. */
	std::string dump() const;
};

}  // namespace forest_slam::pipeline
