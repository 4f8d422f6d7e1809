#include <forest_slam/pipeline/mapping_config.h>

#include <mrpt/config/CConfigFileMemory.h>

#include <algorithm>

namespace forest_slam::pipeline
{
MappingConfig MappingConfig::load(core::TrackedConfig& cfg)
{
	MappingConfig m;
	m.pipeline.loadFromConfigFile(cfg, "pipeline");
	m.forest_map.loadFromConfigFile(cfg, "forest_map");
	m.loop.loadFromConfigFile(cfg, "loop");
	m.trees.loadFromConfigFile(cfg, "trees");
	m.odometry.odometry.loadFromConfigFile(cfg, "odometry");
	m.odometry.registration.loadFromConfigFile(cfg, "registration");
	m.odometry.local_map.loadFromConfigFile(cfg, "local_map");
	m.odometry.imu.loadFromConfigFile(cfg, "imu");
	m.odometry.ground.loadFromConfigFile(cfg, "ground");
	m.odometry.cluster.loadFromConfigFile(cfg, "cluster");
	m.odometry.features.loadFromConfigFile(cfg, "features");
	m.outputs.loadFromConfigFile(cfg, "outputs");
	m.georeference.loadFromConfigFile(cfg, "georeference");
	// An online INI's sensor sections (driver = ...) and [online] belong to
	// `forest-slam online`, which checks them; accepting them here lets the
	// same INI re-map the recorded raw.rawlog offline.
	std::vector<std::string> sections;
	cfg.getAllSections(sections);
	for (const auto& s : sections)
	{
		std::vector<std::string> keys;
		cfg.getAllKeys(s, keys);
		if (s == "online" ||
		    std::count(keys.begin(), keys.end(), std::string("driver")))
			cfg.acceptSection(s);
	}
	cfg.checkNoUnknownKeys();
	return m;
}

MappingConfig MappingConfig::loadFile(const std::string& path)
{
	auto cfg = core::TrackedConfig::fromFile(path);
	return load(cfg);
}

std::string MappingConfig::dump() const
{
	mrpt::config::CConfigFileMemory mem;
	pipeline.saveToConfigFile(mem, "pipeline");
	forest_map.saveToConfigFile(mem, "forest_map");
	loop.saveToConfigFile(mem, "loop");
	trees.saveToConfigFile(mem, "trees");
	odometry.odometry.saveToConfigFile(mem, "odometry");
	odometry.registration.saveToConfigFile(mem, "registration");
	odometry.local_map.saveToConfigFile(mem, "local_map");
	odometry.imu.saveToConfigFile(mem, "imu");
	odometry.ground.saveToConfigFile(mem, "ground");
	odometry.cluster.saveToConfigFile(mem, "cluster");
	odometry.features.saveToConfigFile(mem, "features");
	outputs.saveToConfigFile(mem, "outputs");
	georeference.saveToConfigFile(mem, "georeference");
	return mem.getContent();
}

}  // namespace forest_slam::pipeline
