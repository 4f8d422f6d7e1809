#pragma once
// Every parameter of a simulated run, one INI section per struct. Defaults
// are those of the handheld scenario; doc/simulator.md lists every key.
#include <forest_slam/core/config.h>
#include <forest_slam/sim/faults.h>

#include <mrpt/config/CLoadableOptions.h>
#include <mrpt/poses/CPose3D.h>
#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <string>

namespace forest_slam::sim
{
/** Rigid mount of a sensor on the vehicle (body) frame, keys pose_*. */
struct Mount
{
	double x_m = 0, y_m = 0, z_m = 0;
	double yaw_deg = 0, pitch_deg = 0, roll_deg = 0;
	void load(const mrpt::config::CConfigFileBase& c, const std::string& s);
	void save(mrpt::config::CConfigFileBase& c, const std::string& s) const;
	/** sensor -> body */
	Eigen::Isometry3d toIsometry() const;
	mrpt::poses::CPose3D toCPose3D() const;
};

/** [sim] */
struct RunOptions : public mrpt::config::CLoadableOptions
{
	uint64_t seed = 1;  ///< overridden by forest-sim --seed
	double start_time_unix_s = 1700000000.0;  ///< first lidar firing
	int threads = 2;                          ///< ray casting threads
	/** false: no range noise, dropouts, intensity noise, IMU noise/bias,
	 * GNSS error (geometry and GNSS outages stay). */
	bool noise = true;
	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

/** [world]: extent and the open area around the start. */
struct WorldOptions : public mrpt::config::CLoadableOptions
{
	double margin_m = 40;            ///< world = path bounding box + margin
	double open_area_radius_m = 25;  ///< tree-free flat yard at the start
	double grid_cell_m = 2.0;        ///< ray casting acceleration grid
	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

/** [terrain] */
struct TerrainOptions : public mrpt::config::CLoadableOptions
{
	double grid_step_m = 2.0;
	double elevation_range_m = 6.0;  ///< target peak-to-peak
	double max_slope_deg = 12.0;     ///< the field is scaled down to respect it
	double feature_size_m = 60.0;    ///< shortest hill wavelength
	double roughness_m = 0.04;       ///< forest floor micro relief, 1-sigma
	double roughness_step_m = 0.25;
	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

/** [trees] */
struct TreeOptions : public mrpt::config::CLoadableOptions
{
	double stems_per_ha = 500;
	double density_variation = 0.3;  ///< 0 uniform .. 1 strongly patchy
	double hard_core_m = 1.5;  ///< min bark-to-bark distance between stems
	double dbh_median_m = 0.25, dbh_sigma_log = 0.45;
	double dbh_min_m = 0.10, dbh_max_m = 0.75;
	double height_min_m = 15, height_max_m = 30, height_noise_m = 1.5;
	double lean_max_deg = 5;
	double ellipticity_max = 0.04;  ///< semi-axes r(1+e), r(1-e)
	double bark_roughness_m = 0.003;
	double crown_base_min_fraction = 0.35, crown_base_max_fraction = 0.6;
	double crown_radius_min_m = 1.0, crown_radius_per_dbh = 5.0;
	double crown_extinction_per_m = 0.8;
	double whorl_spacing_m = 0.8;
	int branches_per_whorl = 4;
	double branch_radius_max_m = 0.04;
	double dead_branches_per_m = 1.0;
	double dead_branch_min_height_m = 2.0;
	double path_clearance_m = 1.2;  ///< bark to path centre line
	/** random: hard-core process (stems_per_ha); rows: a plantation, one
	 * tree every row_tree_spacing_m along rows row_spacing_m apart, at
	 * row_azimuth_deg (from east), each moved by up to row_jitter_m. */
	std::string layout = "random";
	double row_spacing_m = 3.0, row_tree_spacing_m = 2.5;
	double row_azimuth_deg = 0, row_jitter_m = 0.1;
	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

/** [saplings] */
struct SaplingOptions : public mrpt::config::CLoadableOptions
{
	double per_ha = 150;
	double height_min_m = 1.5, height_max_m = 5.0;
	double dbh_min_m = 0.01, dbh_max_m = 0.06;
	double crown_extinction_per_m = 1.5;
	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

/** [shrubs] */
struct ShrubOptions : public mrpt::config::CLoadableOptions
{
	double cover_fraction = 0.2;  ///< of the forested area
	double patch_radius_min_m = 3, patch_radius_max_m = 8;
	double radius_min_m = 0.4, radius_max_m = 1.2;
	double height_min_m = 0.5, height_max_m = 2.0;
	double extinction_per_m = 1.2;  ///< see-through: ~30% pass 1 m
	double path_clearance_m = 0.8;
	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

/** [trail]: the first and last `length_m` of the path run on a trail. */
struct TrailOptions : public mrpt::config::CLoadableOptions
{
	double length_m = 60;
	double width_m = 3.0;
	double roughness_factor = 0.3;
	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

/** [structures]: buildings and vehicles in the open area. */
struct StructureOptions : public mrpt::config::CLoadableOptions
{
	int buildings = 3;
	double building_size_min_m = 6, building_size_max_m = 14;
	double building_height_min_m = 3, building_height_max_m = 7;
	int vehicles = 2;
	double path_clearance_m = 3.0;
	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

enum class MotionType
{
	Handheld,
	Robot
};

/** [motion] */
struct MotionOptions : public mrpt::config::CLoadableOptions
{
	std::string type = "handheld";  ///< handheld | robot
	double speed_min_mps = 1.0, speed_max_mps = 1.3;
	double accel_mps2 = 0.5;
	double start_pause_s = 2.0, end_pause_s = 2.0;
	double body_height_m = 1.3;  ///< body frame above the ground
	double loop_radius_x_m = 55, loop_radius_y_m = 45;
	double loop_wobble = 0.15;        ///< handheld: radial irregularity
	double inner_loop_radius_m = 12;  ///< handheld; 0 = no inner loop
	int loops = 1;                    ///< robot: laps of the circuit
	/** robot: loop (the jittered rectangle) or out_and_back (east along
	 * 2 x loop_radius_x_m and back on the same line, `loops` times). */
	std::string route = "loop";
	// handheld gait
	double bob_amplitude_m = 0.03;
	double step_frequency_hz = 1.8;
	double sway_deg = 4.0;
	// robot
	double vibration_deg = 0.5;
	double vibration_z_m = 0.005;
	double vibration_frequency_hz = 12.0;
	double stop_probability = 0.3;  ///< per straight segment
	double stop_duration_s = 3.0;
	double turn_rate_deg_s = 30.0;
	double corner_jitter_m = 4.0;
	double knot_spacing_s = 0.005;  ///< C2 spline knots
	MotionType motionType() const;
	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

/** [lidar] */
struct LidarOptions : public mrpt::config::CLoadableOptions
{
	std::string model = "VLP16";  ///< VLP16 | HDL32 | OS1-64
	double rate_hz = 10.0;
	double azimuth_step_deg = 0;              ///< 0: model default
	bool clockwise = true;                    ///< Velodyne spin direction
	double min_range_m = 0, max_range_m = 0;  ///< 0: model default
	double range_resolution_m = 0.002;
	double range_noise_m = 0.025;
	/** Classes whose returns get the range noise: "all", or a list of
	 * ground, stem, crown, shrub, structure (comma or space separated):
	 * to find which surfaces' noise an effect comes from. */
	std::string range_noise_classes = "all";
	/** Bit (1 << Label) set for each class of range_noise_classes; none
	 * if a class is unknown. */
	std::optional<uint32_t> rangeNoiseMask() const;
	double dropout_probability = 0.005;
	double intensity_noise = 2.0;
	bool gt_layers = true;  ///< "gt_label" / "gt_tree" range layers
	Mount mount{0, 0, 0.15};
	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

/** [imu] */
struct ImuOptions : public mrpt::config::CLoadableOptions
{
	double rate_hz = 200.0;
	double gyro_noise_density = 2e-4;  ///< rad/s/sqrt(Hz)
	double gyro_bias_sigma_rad_s = 0.003;
	double gyro_bias_walk = 2e-5;       ///< rad/s^2/sqrt(Hz)
	double accel_noise_density = 2e-3;  ///< m/s^2/sqrt(Hz)
	double accel_bias_sigma_mps2 = 0.03;
	double accel_bias_walk = 3e-4;  ///< m/s^3/sqrt(Hz)
	double gravity_mps2 = 9.81;
	Mount mount{0.02, 0, 0.05};
	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

/** [gnss] */
struct GnssOptions : public mrpt::config::CLoadableOptions
{
	bool enabled = true;
	double rate_hz = 1.0;
	/** Geodetic point of the world origin (the start, on the ground). */
	double origin_lat_deg = 59.6635, origin_lon_deg = 10.7677;
	double origin_height_m = 95.0;
	double open_sigma_m = 0.03;          ///< horizontal 1-sigma, open sky
	double canopy_sigma_m = 2.0;         ///< horizontal 1-sigma, under canopy
	double canopy_correlation_s = 20.0;  ///< multipath error time constant
	double vertical_factor = 1.7;        ///< vertical sigma / horizontal sigma
	double sky_open_fraction = 0.8;      ///< >= this: open-sky fix
	double sky_min_fraction = 0.45;      ///< < this: no fix
	int sky_rays = 48;
	int open_fix_quality = 4;  ///< NMEA quality in the open (4 = RTK)
	Mount mount{0, 0, 0.3};
	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

/** [output] */
struct OutputOptions : public mrpt::config::CLoadableOptions
{
	double gt_rate_hz = 200.0;            ///< gt_trajectory.tum rate
	int compress_level = 1;               ///< rawlog gzip level
	std::string bag_compression = "lz4";  ///< none | lz4 | bz2
	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& s) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& s) const override;
};

struct SimOptions
{
	RunOptions run;
	WorldOptions world;
	TerrainOptions terrain;
	TreeOptions trees;
	SaplingOptions saplings;
	ShrubOptions shrubs;
	TrailOptions trail;
	StructureOptions structures;
	MotionOptions motion;
	LidarOptions lidar;
	ImuOptions imu;
	GnssOptions gnss;
	OutputOptions output;
	FaultOptions faults;  ///< [faults], faults.h

	/** Loads every section and rejects unknown keys (ConfigError naming
	 * file/section/key) and values out of their valid range. The
	 * [ground_truth] section that forest-sim writes into scenario.ini is
	 * accepted and ignored, so a scenario.ini can be run again. */
	static SimOptions load(core::TrackedConfig& cfg);
	static SimOptions loadFile(const std::string& path);
	static SimOptions loadText(const std::string& text,
	                           const std::string& origin = "<text>");
	/** Throws ConfigError naming section/key for a value out of range. */
	void validate(const std::string& origin) const;
	/** All effective parameters as INI text. */
	std::string toIni() const;
	/** Copy with every noise source zeroed when run.noise is false. */
	SimOptions effective() const;
};

}  // namespace forest_slam::sim
