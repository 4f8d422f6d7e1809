#include <forest_slam/pipeline/mapping_config.h>

#include <mrpt/config/CConfigFileMemory.h>

namespace forest_slam::pipeline
{
MappingConfig MappingConfig::load(core::TrackedConfig& cfg)
{
	MappingConfig m;
	m.pipeline.loadFromConfigFile(cfg, "pipeline");
	m.forest_map.loadFromConfigFile(cfg, "forest_map");
	m.trees.loadFromConfigFile(cfg, "trees");
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
	trees.saveToConfigFile(mem, "trees");
	return mem.getContent();
}

}  // namespace forest_slam::pipeline
