#include <forest_slam/core/lidar_model.h>
#include <forest_slam/sim/options.h>
#include <forest_slam/sim/world.h>

#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/system/string_utils.h>

#include <cmath>
#include <cstdio>

namespace forest_slam::sim
{
namespace
{
constexpr double kDeg = M_PI / 180.0;

// MRPT's write(double) prints "%e" with padding; scenario.ini is read by
// people, so values are written in the shortest exact-enough form.
void put(mrpt::config::CConfigFileBase& c, const std::string& s,
         const std::string& k, double v)
{
	char buf[64];
	std::snprintf(buf, sizeof(buf), "%.12g", v);
	c.write(s, k, std::string(buf));
}
void put(mrpt::config::CConfigFileBase& c, const std::string& s,
         const std::string& k, int v)
{
	c.write(s, k, std::to_string(v));
}
void put(mrpt::config::CConfigFileBase& c, const std::string& s,
         const std::string& k, uint64_t v)
{
	c.write(s, k, std::to_string(v));
}
void put(mrpt::config::CConfigFileBase& c, const std::string& s,
         const std::string& k, bool v)
{
	c.write(s, k, std::string(v ? "true" : "false"));
}
void put(mrpt::config::CConfigFileBase& c, const std::string& s,
         const std::string& k, const std::string& v)
{
	c.write(s, k, v);
}
#define FS_SAVE(cfg, section, field) put(cfg, section, #field, field)

/** Range checks name the key like the loader does. */
class Checker
{
   public:
	explicit Checker(std::string origin) : origin_(std::move(origin)) {}
	void operator()(bool ok, const std::string& section, const std::string& key,
	                const std::string& expected) const
	{
		if (!ok)
			throw core::ConfigError(origin_ + ": [" + section + "] " + key +
			                        ": expected " + expected);
	}

   private:
	std::string origin_;
};
}  // namespace

void Mount::load(const mrpt::config::CConfigFileBase& c, const std::string& s)
{
	core::loadOption(c, s, "pose_x_m", x_m);
	core::loadOption(c, s, "pose_y_m", y_m);
	core::loadOption(c, s, "pose_z_m", z_m);
	core::loadOption(c, s, "pose_yaw_deg", yaw_deg);
	core::loadOption(c, s, "pose_pitch_deg", pitch_deg);
	core::loadOption(c, s, "pose_roll_deg", roll_deg);
}

void Mount::save(mrpt::config::CConfigFileBase& c, const std::string& s) const
{
	put(c, s, "pose_x_m", x_m);
	put(c, s, "pose_y_m", y_m);
	put(c, s, "pose_z_m", z_m);
	put(c, s, "pose_yaw_deg", yaw_deg);
	put(c, s, "pose_pitch_deg", pitch_deg);
	put(c, s, "pose_roll_deg", roll_deg);
}

Eigen::Isometry3d Mount::toIsometry() const
{
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	T.linear() =
	    (Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitZ()) *
	     Eigen::AngleAxisd(pitch_deg * kDeg, Eigen::Vector3d::UnitY()) *
	     Eigen::AngleAxisd(roll_deg * kDeg, Eigen::Vector3d::UnitX()))
	        .toRotationMatrix();
	T.translation() = Eigen::Vector3d(x_m, y_m, z_m);
	return T;
}

mrpt::poses::CPose3D Mount::toCPose3D() const
{
	return mrpt::poses::CPose3D(x_m, y_m, z_m, yaw_deg * kDeg, pitch_deg * kDeg,
	                            roll_deg * kDeg);
}

void RunOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                    const std::string& s)
{
	FS_LOAD(c, s, seed);
	FS_LOAD(c, s, start_time_unix_s);
	FS_LOAD(c, s, threads);
	FS_LOAD(c, s, noise);
}
void RunOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                  const std::string& s) const
{
	FS_SAVE(c, s, seed);
	FS_SAVE(c, s, start_time_unix_s);
	FS_SAVE(c, s, threads);
	FS_SAVE(c, s, noise);
}

void WorldOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                      const std::string& s)
{
	FS_LOAD(c, s, margin_m);
	FS_LOAD(c, s, open_area_radius_m);
	FS_LOAD(c, s, grid_cell_m);
}
void WorldOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                    const std::string& s) const
{
	FS_SAVE(c, s, margin_m);
	FS_SAVE(c, s, open_area_radius_m);
	FS_SAVE(c, s, grid_cell_m);
}

void TerrainOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                        const std::string& s)
{
	FS_LOAD(c, s, grid_step_m);
	FS_LOAD(c, s, elevation_range_m);
	FS_LOAD(c, s, max_slope_deg);
	FS_LOAD(c, s, feature_size_m);
	FS_LOAD(c, s, roughness_m);
	FS_LOAD(c, s, roughness_step_m);
}
void TerrainOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                      const std::string& s) const
{
	FS_SAVE(c, s, grid_step_m);
	FS_SAVE(c, s, elevation_range_m);
	FS_SAVE(c, s, max_slope_deg);
	FS_SAVE(c, s, feature_size_m);
	FS_SAVE(c, s, roughness_m);
	FS_SAVE(c, s, roughness_step_m);
}

void TreeOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                     const std::string& s)
{
	FS_LOAD(c, s, stems_per_ha);
	FS_LOAD(c, s, density_variation);
	FS_LOAD(c, s, hard_core_m);
	FS_LOAD(c, s, dbh_median_m);
	FS_LOAD(c, s, dbh_sigma_log);
	FS_LOAD(c, s, dbh_min_m);
	FS_LOAD(c, s, dbh_max_m);
	FS_LOAD(c, s, height_min_m);
	FS_LOAD(c, s, height_max_m);
	FS_LOAD(c, s, height_noise_m);
	FS_LOAD(c, s, lean_max_deg);
	FS_LOAD(c, s, ellipticity_max);
	FS_LOAD(c, s, bark_roughness_m);
	FS_LOAD(c, s, crown_base_min_fraction);
	FS_LOAD(c, s, crown_base_max_fraction);
	FS_LOAD(c, s, crown_radius_min_m);
	FS_LOAD(c, s, crown_radius_per_dbh);
	FS_LOAD(c, s, crown_extinction_per_m);
	FS_LOAD(c, s, whorl_spacing_m);
	FS_LOAD(c, s, branches_per_whorl);
	FS_LOAD(c, s, branch_radius_max_m);
	FS_LOAD(c, s, dead_branches_per_m);
	FS_LOAD(c, s, dead_branch_min_height_m);
	FS_LOAD(c, s, path_clearance_m);
	FS_LOAD(c, s, layout);
	FS_LOAD(c, s, row_spacing_m);
	FS_LOAD(c, s, row_tree_spacing_m);
	FS_LOAD(c, s, row_azimuth_deg);
	FS_LOAD(c, s, row_jitter_m);
}
void TreeOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                   const std::string& s) const
{
	FS_SAVE(c, s, stems_per_ha);
	FS_SAVE(c, s, density_variation);
	FS_SAVE(c, s, hard_core_m);
	FS_SAVE(c, s, dbh_median_m);
	FS_SAVE(c, s, dbh_sigma_log);
	FS_SAVE(c, s, dbh_min_m);
	FS_SAVE(c, s, dbh_max_m);
	FS_SAVE(c, s, height_min_m);
	FS_SAVE(c, s, height_max_m);
	FS_SAVE(c, s, height_noise_m);
	FS_SAVE(c, s, lean_max_deg);
	FS_SAVE(c, s, ellipticity_max);
	FS_SAVE(c, s, bark_roughness_m);
	FS_SAVE(c, s, crown_base_min_fraction);
	FS_SAVE(c, s, crown_base_max_fraction);
	FS_SAVE(c, s, crown_radius_min_m);
	FS_SAVE(c, s, crown_radius_per_dbh);
	FS_SAVE(c, s, crown_extinction_per_m);
	FS_SAVE(c, s, whorl_spacing_m);
	FS_SAVE(c, s, branches_per_whorl);
	FS_SAVE(c, s, branch_radius_max_m);
	FS_SAVE(c, s, dead_branches_per_m);
	FS_SAVE(c, s, dead_branch_min_height_m);
	FS_SAVE(c, s, path_clearance_m);
	FS_SAVE(c, s, layout);
	FS_SAVE(c, s, row_spacing_m);
	FS_SAVE(c, s, row_tree_spacing_m);
	FS_SAVE(c, s, row_azimuth_deg);
	FS_SAVE(c, s, row_jitter_m);
}

void SaplingOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                        const std::string& s)
{
	FS_LOAD(c, s, per_ha);
	FS_LOAD(c, s, height_min_m);
	FS_LOAD(c, s, height_max_m);
	FS_LOAD(c, s, dbh_min_m);
	FS_LOAD(c, s, dbh_max_m);
	FS_LOAD(c, s, crown_extinction_per_m);
}
void SaplingOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                      const std::string& s) const
{
	FS_SAVE(c, s, per_ha);
	FS_SAVE(c, s, height_min_m);
	FS_SAVE(c, s, height_max_m);
	FS_SAVE(c, s, dbh_min_m);
	FS_SAVE(c, s, dbh_max_m);
	FS_SAVE(c, s, crown_extinction_per_m);
}

void ShrubOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                      const std::string& s)
{
	FS_LOAD(c, s, cover_fraction);
	FS_LOAD(c, s, patch_radius_min_m);
	FS_LOAD(c, s, patch_radius_max_m);
	FS_LOAD(c, s, radius_min_m);
	FS_LOAD(c, s, radius_max_m);
	FS_LOAD(c, s, height_min_m);
	FS_LOAD(c, s, height_max_m);
	FS_LOAD(c, s, extinction_per_m);
	FS_LOAD(c, s, path_clearance_m);
}
void ShrubOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                    const std::string& s) const
{
	FS_SAVE(c, s, cover_fraction);
	FS_SAVE(c, s, patch_radius_min_m);
	FS_SAVE(c, s, patch_radius_max_m);
	FS_SAVE(c, s, radius_min_m);
	FS_SAVE(c, s, radius_max_m);
	FS_SAVE(c, s, height_min_m);
	FS_SAVE(c, s, height_max_m);
	FS_SAVE(c, s, extinction_per_m);
	FS_SAVE(c, s, path_clearance_m);
}

void TrailOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                      const std::string& s)
{
	FS_LOAD(c, s, length_m);
	FS_LOAD(c, s, width_m);
	FS_LOAD(c, s, roughness_factor);
}
void TrailOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                    const std::string& s) const
{
	FS_SAVE(c, s, length_m);
	FS_SAVE(c, s, width_m);
	FS_SAVE(c, s, roughness_factor);
}

void StructureOptions::loadFromConfigFile(
    const mrpt::config::CConfigFileBase& c, const std::string& s)
{
	FS_LOAD(c, s, buildings);
	FS_LOAD(c, s, building_size_min_m);
	FS_LOAD(c, s, building_size_max_m);
	FS_LOAD(c, s, building_height_min_m);
	FS_LOAD(c, s, building_height_max_m);
	FS_LOAD(c, s, vehicles);
	FS_LOAD(c, s, path_clearance_m);
}
void StructureOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                        const std::string& s) const
{
	FS_SAVE(c, s, buildings);
	FS_SAVE(c, s, building_size_min_m);
	FS_SAVE(c, s, building_size_max_m);
	FS_SAVE(c, s, building_height_min_m);
	FS_SAVE(c, s, building_height_max_m);
	FS_SAVE(c, s, vehicles);
	FS_SAVE(c, s, path_clearance_m);
}

MotionType MotionOptions::motionType() const
{
	return type == "robot" ? MotionType::Robot : MotionType::Handheld;
}

void MotionOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                       const std::string& s)
{
	FS_LOAD(c, s, type);
	FS_LOAD(c, s, speed_min_mps);
	FS_LOAD(c, s, speed_max_mps);
	FS_LOAD(c, s, accel_mps2);
	FS_LOAD(c, s, start_pause_s);
	FS_LOAD(c, s, end_pause_s);
	FS_LOAD(c, s, body_height_m);
	FS_LOAD(c, s, loop_radius_x_m);
	FS_LOAD(c, s, loop_radius_y_m);
	FS_LOAD(c, s, loop_wobble);
	FS_LOAD(c, s, inner_loop_radius_m);
	FS_LOAD(c, s, loops);
	FS_LOAD(c, s, route);
	FS_LOAD(c, s, bob_amplitude_m);
	FS_LOAD(c, s, step_frequency_hz);
	FS_LOAD(c, s, sway_deg);
	FS_LOAD(c, s, vibration_deg);
	FS_LOAD(c, s, vibration_z_m);
	FS_LOAD(c, s, vibration_frequency_hz);
	FS_LOAD(c, s, stop_probability);
	FS_LOAD(c, s, stop_duration_s);
	FS_LOAD(c, s, turn_rate_deg_s);
	FS_LOAD(c, s, corner_jitter_m);
	FS_LOAD(c, s, knot_spacing_s);
}
void MotionOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                     const std::string& s) const
{
	FS_SAVE(c, s, type);
	FS_SAVE(c, s, speed_min_mps);
	FS_SAVE(c, s, speed_max_mps);
	FS_SAVE(c, s, accel_mps2);
	FS_SAVE(c, s, start_pause_s);
	FS_SAVE(c, s, end_pause_s);
	FS_SAVE(c, s, body_height_m);
	FS_SAVE(c, s, loop_radius_x_m);
	FS_SAVE(c, s, loop_radius_y_m);
	FS_SAVE(c, s, loop_wobble);
	FS_SAVE(c, s, inner_loop_radius_m);
	FS_SAVE(c, s, loops);
	FS_SAVE(c, s, route);
	FS_SAVE(c, s, bob_amplitude_m);
	FS_SAVE(c, s, step_frequency_hz);
	FS_SAVE(c, s, sway_deg);
	FS_SAVE(c, s, vibration_deg);
	FS_SAVE(c, s, vibration_z_m);
	FS_SAVE(c, s, vibration_frequency_hz);
	FS_SAVE(c, s, stop_probability);
	FS_SAVE(c, s, stop_duration_s);
	FS_SAVE(c, s, turn_rate_deg_s);
	FS_SAVE(c, s, corner_jitter_m);
	FS_SAVE(c, s, knot_spacing_s);
}

std::optional<uint32_t> LidarOptions::rangeNoiseMask() const
{
	static const std::pair<const char*, Label> kClasses[] = {
	    {"ground", kLabelGround},
	    {"stem", kLabelStem},
	    {"crown", kLabelCrown},
	    {"shrub", kLabelShrub},
	    {"structure", kLabelStructure}};
	std::vector<std::string> words;
	mrpt::system::tokenize(range_noise_classes, ", \t", words);
	uint32_t mask = 0;
	for (const auto& word : words)
	{
		bool found = word == "all";
		if (found) mask = ~0u;
		for (const auto& [name, label] : kClasses)
			if (word == name) mask |= 1u << label, found = true;
		if (!found) return std::nullopt;
	}
	return mask;
}

void LidarOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                      const std::string& s)
{
	FS_LOAD(c, s, model);
	FS_LOAD(c, s, rate_hz);
	FS_LOAD(c, s, azimuth_step_deg);
	FS_LOAD(c, s, clockwise);
	FS_LOAD(c, s, min_range_m);
	FS_LOAD(c, s, max_range_m);
	FS_LOAD(c, s, range_resolution_m);
	FS_LOAD(c, s, range_noise_m);
	FS_LOAD(c, s, range_noise_classes);
	FS_LOAD(c, s, dropout_probability);
	FS_LOAD(c, s, intensity_noise);
	FS_LOAD(c, s, gt_layers);
	mount.load(c, s);
}
void LidarOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                    const std::string& s) const
{
	FS_SAVE(c, s, model);
	FS_SAVE(c, s, rate_hz);
	FS_SAVE(c, s, azimuth_step_deg);
	FS_SAVE(c, s, clockwise);
	FS_SAVE(c, s, min_range_m);
	FS_SAVE(c, s, max_range_m);
	FS_SAVE(c, s, range_resolution_m);
	FS_SAVE(c, s, range_noise_m);
	FS_SAVE(c, s, range_noise_classes);
	FS_SAVE(c, s, dropout_probability);
	FS_SAVE(c, s, intensity_noise);
	FS_SAVE(c, s, gt_layers);
	mount.save(c, s);
}

void ImuOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                    const std::string& s)
{
	FS_LOAD(c, s, rate_hz);
	FS_LOAD(c, s, gyro_noise_density);
	FS_LOAD(c, s, gyro_bias_sigma_rad_s);
	FS_LOAD(c, s, gyro_bias_walk);
	FS_LOAD(c, s, accel_noise_density);
	FS_LOAD(c, s, accel_bias_sigma_mps2);
	FS_LOAD(c, s, accel_bias_walk);
	FS_LOAD(c, s, gravity_mps2);
	mount.load(c, s);
}
void ImuOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                  const std::string& s) const
{
	FS_SAVE(c, s, rate_hz);
	FS_SAVE(c, s, gyro_noise_density);
	FS_SAVE(c, s, gyro_bias_sigma_rad_s);
	FS_SAVE(c, s, gyro_bias_walk);
	FS_SAVE(c, s, accel_noise_density);
	FS_SAVE(c, s, accel_bias_sigma_mps2);
	FS_SAVE(c, s, accel_bias_walk);
	FS_SAVE(c, s, gravity_mps2);
	mount.save(c, s);
}

void GnssOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                     const std::string& s)
{
	FS_LOAD(c, s, enabled);
	FS_LOAD(c, s, rate_hz);
	FS_LOAD(c, s, origin_lat_deg);
	FS_LOAD(c, s, origin_lon_deg);
	FS_LOAD(c, s, origin_height_m);
	FS_LOAD(c, s, open_sigma_m);
	FS_LOAD(c, s, canopy_sigma_m);
	FS_LOAD(c, s, canopy_correlation_s);
	FS_LOAD(c, s, vertical_factor);
	FS_LOAD(c, s, sky_open_fraction);
	FS_LOAD(c, s, sky_min_fraction);
	FS_LOAD(c, s, sky_rays);
	FS_LOAD(c, s, open_fix_quality);
	mount.load(c, s);
}
void GnssOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                   const std::string& s) const
{
	FS_SAVE(c, s, enabled);
	FS_SAVE(c, s, rate_hz);
	FS_SAVE(c, s, origin_lat_deg);
	FS_SAVE(c, s, origin_lon_deg);
	FS_SAVE(c, s, origin_height_m);
	FS_SAVE(c, s, open_sigma_m);
	FS_SAVE(c, s, canopy_sigma_m);
	FS_SAVE(c, s, canopy_correlation_s);
	FS_SAVE(c, s, vertical_factor);
	FS_SAVE(c, s, sky_open_fraction);
	FS_SAVE(c, s, sky_min_fraction);
	FS_SAVE(c, s, sky_rays);
	FS_SAVE(c, s, open_fix_quality);
	mount.save(c, s);
}

void OutputOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
                                       const std::string& s)
{
	FS_LOAD(c, s, gt_rate_hz);
	FS_LOAD(c, s, compress_level);
	FS_LOAD(c, s, bag_compression);
}
void OutputOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                     const std::string& s) const
{
	FS_SAVE(c, s, gt_rate_hz);
	FS_SAVE(c, s, compress_level);
	FS_SAVE(c, s, bag_compression);
}

SimOptions SimOptions::load(core::TrackedConfig& cfg)
{
	SimOptions o;
	o.run.loadFromConfigFile(cfg, "sim");
	o.world.loadFromConfigFile(cfg, "world");
	o.terrain.loadFromConfigFile(cfg, "terrain");
	o.trees.loadFromConfigFile(cfg, "trees");
	o.saplings.loadFromConfigFile(cfg, "saplings");
	o.shrubs.loadFromConfigFile(cfg, "shrubs");
	o.trail.loadFromConfigFile(cfg, "trail");
	o.structures.loadFromConfigFile(cfg, "structures");
	o.motion.loadFromConfigFile(cfg, "motion");
	o.lidar.loadFromConfigFile(cfg, "lidar");
	o.imu.loadFromConfigFile(cfg, "imu");
	o.gnss.loadFromConfigFile(cfg, "gnss");
	o.output.loadFromConfigFile(cfg, "output");
	o.faults.loadFromConfigFile(cfg, "faults");
	cfg.acceptSection("ground_truth");
	cfg.checkNoUnknownKeys();
	o.validate(cfg.origin());
	return o;
}

SimOptions SimOptions::loadFile(const std::string& path)
{
	auto cfg = core::TrackedConfig::fromFile(path);
	return load(cfg);
}

SimOptions SimOptions::loadText(const std::string& text,
                                const std::string& origin)
{
	auto cfg = core::TrackedConfig::fromText(text, origin);
	return load(cfg);
}

void SimOptions::validate(const std::string& origin) const
{
	const Checker check(origin);
	check(run.threads >= 1 && run.threads <= 64, "sim", "threads", "1..64");
	check(world.margin_m >= 0, "world", "margin_m", ">= 0");
	check(world.open_area_radius_m >= 0, "world", "open_area_radius_m", ">= 0");
	check(world.grid_cell_m >= 0.5 && world.grid_cell_m <= 20, "world",
	      "grid_cell_m", "0.5..20");
	check(terrain.grid_step_m >= 0.25 && terrain.grid_step_m <= 20, "terrain",
	      "grid_step_m", "0.25..20");
	check(terrain.elevation_range_m >= 0, "terrain", "elevation_range_m",
	      ">= 0");
	check(terrain.max_slope_deg >= 0 && terrain.max_slope_deg < 45, "terrain",
	      "max_slope_deg", "0..45");
	check(terrain.feature_size_m > 2 * terrain.grid_step_m, "terrain",
	      "feature_size_m", "> 2 * grid_step_m");
	check(terrain.roughness_m >= 0 && terrain.roughness_m <= 0.5, "terrain",
	      "roughness_m", "0..0.5");
	check(terrain.roughness_step_m >= 0.05 && terrain.roughness_step_m <= 2,
	      "terrain", "roughness_step_m", "0.05..2");
	check(trees.stems_per_ha >= 0 && trees.stems_per_ha <= 3000, "trees",
	      "stems_per_ha", "0..3000");
	check(trees.density_variation >= 0 && trees.density_variation <= 1, "trees",
	      "density_variation", "0..1");
	check(trees.hard_core_m >= 0, "trees", "hard_core_m", ">= 0");
	check(trees.dbh_min_m > 0 && trees.dbh_min_m <= trees.dbh_max_m &&
	          trees.dbh_max_m < 3,
	      "trees", "dbh_min_m", "0 < dbh_min_m <= dbh_max_m < 3");
	check(trees.dbh_median_m > 0, "trees", "dbh_median_m", "> 0");
	check(trees.dbh_sigma_log >= 0, "trees", "dbh_sigma_log", ">= 0");
	check(trees.height_min_m >= 4 && trees.height_min_m <= trees.height_max_m,
	      "trees", "height_min_m", "4 <= height_min_m <= height_max_m");
	check(trees.lean_max_deg >= 0 && trees.lean_max_deg <= 30, "trees",
	      "lean_max_deg", "0..30");
	check(trees.ellipticity_max >= 0 && trees.ellipticity_max <= 0.3, "trees",
	      "ellipticity_max", "0..0.3");
	check(trees.bark_roughness_m >= 0 && trees.bark_roughness_m <= 0.05,
	      "trees", "bark_roughness_m", "0..0.05");
	check(trees.crown_base_min_fraction > 0.1 &&
	          trees.crown_base_min_fraction <= trees.crown_base_max_fraction &&
	          trees.crown_base_max_fraction < 0.9,
	      "trees", "crown_base_min_fraction",
	      "0.1 < min <= crown_base_max_fraction < 0.9");
	check(trees.crown_extinction_per_m >= 0, "trees", "crown_extinction_per_m",
	      ">= 0");
	check(trees.whorl_spacing_m >= 0.1, "trees", "whorl_spacing_m", ">= 0.1");
	check(trees.branches_per_whorl >= 0 && trees.branches_per_whorl <= 12,
	      "trees", "branches_per_whorl", "0..12");
	check(trees.path_clearance_m >= 0.3, "trees", "path_clearance_m", ">= 0.3");
	check(saplings.per_ha >= 0, "saplings", "per_ha", ">= 0");
	check(saplings.height_min_m > 0.2 &&
	          saplings.height_min_m <= saplings.height_max_m,
	      "saplings", "height_min_m", "0.2 < height_min_m <= height_max_m");
	check(saplings.dbh_min_m > 0 && saplings.dbh_min_m <= saplings.dbh_max_m,
	      "saplings", "dbh_min_m", "0 < dbh_min_m <= dbh_max_m");
	check(shrubs.cover_fraction >= 0 && shrubs.cover_fraction <= 0.8, "shrubs",
	      "cover_fraction", "0..0.8");
	check(shrubs.patch_radius_min_m > 0 &&
	          shrubs.patch_radius_min_m <= shrubs.patch_radius_max_m,
	      "shrubs", "patch_radius_min_m", "0 < min <= patch_radius_max_m");
	check(shrubs.radius_min_m > 0 && shrubs.radius_min_m <= shrubs.radius_max_m,
	      "shrubs", "radius_min_m", "0 < radius_min_m <= radius_max_m");
	check(shrubs.height_min_m > 0 && shrubs.height_min_m <= shrubs.height_max_m,
	      "shrubs", "height_min_m", "0 < height_min_m <= height_max_m");
	check(trail.width_m >= 0, "trail", "width_m", ">= 0");
	check(trail.roughness_factor >= 0 && trail.roughness_factor <= 1, "trail",
	      "roughness_factor", "0..1");
	check(structures.buildings >= 0 && structures.buildings <= 50, "structures",
	      "buildings", "0..50");
	check(structures.vehicles >= 0 && structures.vehicles <= 50, "structures",
	      "vehicles", "0..50");
	check(structures.building_size_min_m > 1 &&
	          structures.building_size_min_m <= structures.building_size_max_m,
	      "structures", "building_size_min_m",
	      "1 < min <= building_size_max_m");
	check(structures.building_height_min_m > 1 &&
	          structures.building_height_min_m <=
	              structures.building_height_max_m,
	      "structures", "building_height_min_m",
	      "1 < min <= building_height_max_m");
	check(motion.type == "handheld" || motion.type == "robot", "motion", "type",
	      "handheld | robot");
	check(motion.route == "loop" ||
	          (motion.route == "out_and_back" && motion.type == "robot"),
	      "motion", "route", "loop | out_and_back (robot only)");
	check(trees.layout == "random" || trees.layout == "rows", "trees",
	      "layout", "random | rows");
	check(trees.row_spacing_m >= 1 && trees.row_tree_spacing_m >= 1, "trees",
	      "row_spacing_m", "row_spacing_m, row_tree_spacing_m >= 1");
	check(trees.row_jitter_m >= 0 && trees.row_jitter_m <= 0.5, "trees",
	      "row_jitter_m", "0..0.5");
	check(motion.speed_min_mps > 0.05 &&
	          motion.speed_min_mps <= motion.speed_max_mps &&
	          motion.speed_max_mps <= 10,
	      "motion", "speed_min_mps",
	      "0.05 < speed_min_mps <= speed_max_mps <= 10");
	check(motion.accel_mps2 >= 0.05 && motion.accel_mps2 <= 5, "motion",
	      "accel_mps2", "0.05..5");
	check(motion.start_pause_s >= 0.1, "motion", "start_pause_s", ">= 0.1");
	check(motion.end_pause_s >= 0.1, "motion", "end_pause_s", ">= 0.1");
	check(motion.body_height_m >= 0, "motion", "body_height_m", ">= 0");
	check(motion.loop_radius_x_m >= 5 && motion.loop_radius_y_m >= 5, "motion",
	      "loop_radius_x_m", "loop radii >= 5 m");
	check(motion.loop_wobble >= 0 && motion.loop_wobble <= 0.4, "motion",
	      "loop_wobble", "0..0.4");
	check(motion.inner_loop_radius_m == 0 ||
	          (motion.inner_loop_radius_m >= 3 &&
	           motion.inner_loop_radius_m <
	               0.6 * std::min(motion.loop_radius_x_m,
	                              motion.loop_radius_y_m)),
	      "motion", "inner_loop_radius_m", "0, or 3 .. 0.6 * min(loop radii)");
	check(motion.loops >= 1 && motion.loops <= 50, "motion", "loops", "1..50");
	check(motion.step_frequency_hz > 0.2 && motion.step_frequency_hz < 5,
	      "motion", "step_frequency_hz", "0.2..5");
	check(motion.sway_deg >= 0 && motion.sway_deg <= 20, "motion", "sway_deg",
	      "0..20");
	check(motion.vibration_frequency_hz > 0 &&
	          motion.vibration_frequency_hz <= 0.2 / motion.knot_spacing_s,
	      "motion", "vibration_frequency_hz",
	      "> 0 and <= 0.2 / knot_spacing_s (the spline must resolve it)");
	check(motion.stop_probability >= 0 && motion.stop_probability <= 1,
	      "motion", "stop_probability", "0..1");
	check(motion.turn_rate_deg_s >= 5 && motion.turn_rate_deg_s <= 180,
	      "motion", "turn_rate_deg_s", "5..180");
	check(motion.knot_spacing_s >= 0.001 && motion.knot_spacing_s <= 0.05,
	      "motion", "knot_spacing_s", "0.001..0.05");
	check(core::findLidarModel(lidar.model) != nullptr, "lidar", "model",
	      "one of VLP16, HDL32, OS1-64");
	check(lidar.rate_hz >= 1 && lidar.rate_hz <= 50, "lidar", "rate_hz",
	      "1..50");
	check(lidar.azimuth_step_deg >= 0 && lidar.azimuth_step_deg <= 5, "lidar",
	      "azimuth_step_deg", "0 (model default) .. 5");
	check(lidar.min_range_m >= 0, "lidar", "min_range_m", ">= 0");
	check(lidar.max_range_m >= 0 && lidar.max_range_m <= 300, "lidar",
	      "max_range_m", "0 (model default) .. 300");
	check(
	    lidar.range_resolution_m >= 0.0005 && lidar.range_resolution_m <= 0.01,
	    "lidar", "range_resolution_m", "0.0005..0.01");
	{
		const auto& m = core::lidarModelByName(lidar.model);
		const double maxr =
		    lidar.max_range_m > 0 ? lidar.max_range_m : m.max_range_m;
		check(maxr / lidar.range_resolution_m < 65535, "lidar",
		      "range_resolution_m", "max range / resolution < 65535 (uint16)");
	}
	check(lidar.range_noise_m >= 0, "lidar", "range_noise_m", ">= 0");
	check(lidar.rangeNoiseMask().has_value(), "lidar", "range_noise_classes",
	      "all, or a list of ground, stem, crown, shrub, structure");
	check(lidar.dropout_probability >= 0 && lidar.dropout_probability <= 1,
	      "lidar", "dropout_probability", "0..1");
	check(lidar.intensity_noise >= 0, "lidar", "intensity_noise", ">= 0");
	check(imu.rate_hz >= 10 && imu.rate_hz <= 2000, "imu", "rate_hz",
	      "10..2000");
	check(imu.gyro_noise_density >= 0 && imu.gyro_bias_sigma_rad_s >= 0 &&
	          imu.gyro_bias_walk >= 0,
	      "imu", "gyro_noise_density", "gyro noise figures >= 0");
	check(imu.accel_noise_density >= 0 && imu.accel_bias_sigma_mps2 >= 0 &&
	          imu.accel_bias_walk >= 0,
	      "imu", "accel_noise_density", "accel noise figures >= 0");
	check(imu.gravity_mps2 > 9 && imu.gravity_mps2 < 10.5, "imu",
	      "gravity_mps2", "9..10.5");
	check(gnss.rate_hz > 0 && gnss.rate_hz <= 20, "gnss", "rate_hz", "0..20");
	check(std::abs(gnss.origin_lat_deg) < 89, "gnss", "origin_lat_deg",
	      "-89..89");
	check(std::abs(gnss.origin_lon_deg) <= 180, "gnss", "origin_lon_deg",
	      "-180..180");
	check(gnss.open_sigma_m >= 0 && gnss.canopy_sigma_m >= 0, "gnss",
	      "canopy_sigma_m", "sigmas >= 0");
	check(gnss.canopy_correlation_s > 0, "gnss", "canopy_correlation_s", "> 0");
	check(gnss.sky_min_fraction >= 0 &&
	          gnss.sky_min_fraction < gnss.sky_open_fraction &&
	          gnss.sky_open_fraction <= 1,
	      "gnss", "sky_min_fraction",
	      "0 <= sky_min_fraction < sky_open_fraction <= 1");
	check(gnss.sky_rays >= 4 && gnss.sky_rays <= 1000, "gnss", "sky_rays",
	      "4..1000");
	check(gnss.open_fix_quality >= 1 && gnss.open_fix_quality <= 5, "gnss",
	      "open_fix_quality", "1..5 (NMEA GGA quality)");
	check(output.gt_rate_hz >= 100 && output.gt_rate_hz <= 2000, "output",
	      "gt_rate_hz", "100..2000");
	check(output.compress_level >= 0 && output.compress_level <= 9, "output",
	      "compress_level", "0..9");
	check(output.bag_compression == "none" || output.bag_compression == "lz4" ||
	          output.bag_compression == "bz2",
	      "output", "bag_compression", "none | lz4 | bz2");
	faults.validate(origin);
}

std::string SimOptions::toIni() const
{
	mrpt::config::CConfigFileMemory m;
	run.saveToConfigFile(m, "sim");
	world.saveToConfigFile(m, "world");
	terrain.saveToConfigFile(m, "terrain");
	trees.saveToConfigFile(m, "trees");
	saplings.saveToConfigFile(m, "saplings");
	shrubs.saveToConfigFile(m, "shrubs");
	trail.saveToConfigFile(m, "trail");
	structures.saveToConfigFile(m, "structures");
	motion.saveToConfigFile(m, "motion");
	lidar.saveToConfigFile(m, "lidar");
	imu.saveToConfigFile(m, "imu");
	gnss.saveToConfigFile(m, "gnss");
	output.saveToConfigFile(m, "output");
	if (faults.any()) faults.saveToConfigFile(m, "faults");
	return m.getContent();
}

SimOptions SimOptions::effective() const
{
	SimOptions o = *this;
	if (!run.noise)
	{
		o.lidar.range_noise_m = 0;
		o.lidar.dropout_probability = 0;
		o.lidar.intensity_noise = 0;
		o.imu.gyro_noise_density = 0;
		o.imu.gyro_bias_sigma_rad_s = 0;
		o.imu.gyro_bias_walk = 0;
		o.imu.accel_noise_density = 0;
		o.imu.accel_bias_sigma_mps2 = 0;
		o.imu.accel_bias_walk = 0;
		o.gnss.open_sigma_m = 0;
		o.gnss.canopy_sigma_m = 0;
	}
	return o;
}

}  // namespace forest_slam::sim
