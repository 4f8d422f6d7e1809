#include <forest_slam/core/lidar_model.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace forest_slam::core
{
namespace
{
constexpr double kDeg = M_PI / 180.0;

LidarModel makeVlp16()
{
	LidarModel m;
	m.name = "VLP16";
	// Laser id order of the VLP-16 datasheet: interleaved -15,+1,-13,+3,...
	for (int id = 0; id < 16; id++)
	{
		const double e = (id % 2 == 0) ? -15.0 + id : 1.0 + (id - 1);
		m.elevation_rad.push_back(e * kDeg);
	}
	m.azimuth_step_rad = 0.2 * kDeg;
	m.min_range_m = 0.5;
	m.max_range_m = 100.0;
	m.range_noise_m = 0.03;
	return m;
}

LidarModel makeHdl32()
{
	LidarModel m;
	m.name = "HDL32";
	// HDL-32E: -30.67 .. +10.67 deg in 4/3 deg steps, interleaved by laser id.
	for (int id = 0; id < 32; id++)
	{
		const int k = (id % 2 == 0) ? id / 2 : 16 + id / 2;
		m.elevation_rad.push_back((-30.67 + k * (4.0 / 3.0)) * kDeg);
	}
	m.azimuth_step_rad = 0.16 * kDeg;
	m.min_range_m = 1.0;
	m.max_range_m = 100.0;
	m.range_noise_m = 0.02;
	return m;
}

LidarModel makeOs1_64()
{
	LidarModel m;
	m.name = "OS1-64";
	// Ouster OS1-64 (gen1): +16.6 .. -16.6 deg, uniform, beam 0 highest.
	for (int id = 0; id < 64; id++)
		m.elevation_rad.push_back((16.6 - id * (33.2 / 63.0)) * kDeg);
	m.azimuth_step_rad = 2 * M_PI / 1024;
	m.min_range_m = 0.8;
	m.max_range_m = 120.0;
	m.range_noise_m = 0.03;
	return m;
}

LidarModel makeVlp32c()
{
	LidarModel m;
	m.name = "VLP32C";
	// VLP-32C datasheet elevations [deg] by laser id (firing order), the
	// order of the raw packets and of the ROS driver's calibration file.
	const double el_deg[32] = {-25,	   -1,	   -1.667, -15.639, -11.31, 0,	   -0.667, -8.843,
							   -7.254, 0.333,  -0.333, -6.148,	-5.333, 1.333, 0.667,  -4,
							   -4.667, 1.667,  1,	   -3.667,	-3.333, 3.333, 2.333,  -2.667,
							   -3,	   7,	   4.667,  -2.333,	-2,		15,	   10.333, -1.333};
	for (double e : el_deg) m.elevation_rad.push_back(e * kDeg);
	m.azimuth_step_rad = 0.2 * kDeg;
	m.min_range_m = 0.5;
	m.max_range_m = 200.0;
	m.range_noise_m = 0.03;
	return m;
}

LidarModel makePandarXt32()
{
	LidarModel m;
	m.name = "PandarXT32";
	// Hesai PandarXT-32: +15 .. -16 deg in 1 deg steps, channel 0 highest.
	for (int id = 0; id < 32; id++) m.elevation_rad.push_back((15.0 - id) * kDeg);
	m.azimuth_step_rad = 0.18 * kDeg;
	m.min_range_m = 0.05;
	m.max_range_m = 120.0;
	m.range_noise_m = 0.01;
	return m;
}

std::string canonical(std::string s)
{
	std::string out;
	for (char c : s)
		if (std::isalnum(static_cast<unsigned char>(c)))
			out += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
	if (out == "HDL32E") out = "HDL32";
	if (out == "VLP16PUCK" || out == "VLP16HIRES") out = "VLP16";
	if (out == "VLP32" || out == "ULTRAPUCK") out = "VLP32C";
	if (out == "XT32" || out == "PANDARXT") out = "PANDARXT32";
	return out;
}

const std::vector<LidarModel>& models()
{
	static const std::vector<LidarModel> all = {makeVlp16(), makeHdl32(),
												makeOs1_64(), makeVlp32c(),
												makePandarXt32()};
	return all;
}
}  // namespace

std::vector<int> LidarModel::rowsByElevation() const
{
	std::vector<int> idx(elevation_rad.size());
	std::iota(idx.begin(), idx.end(), 0);
	std::sort(idx.begin(), idx.end(), [this](int a, int b) {
		return elevation_rad[a] < elevation_rad[b];
	});
	return idx;
}

const LidarModel* findLidarModel(const std::string& name)
{
	const auto c = canonical(name);
	for (const auto& m : models())
		if (canonical(m.name) == c) return &m;
	return nullptr;
}

const LidarModel& lidarModelByName(const std::string& name)
{
	if (const auto* m = findLidarModel(name)) return *m;
	std::string known;
	for (const auto& n : knownLidarModels()) known += (known.empty() ? "" : ", ") + n;
	throw std::invalid_argument(
		"unknown lidar model '" + name + "' (known: " + known + ")");
}

std::vector<std::string> knownLidarModels()
{
	std::vector<std::string> names;
	for (const auto& m : models()) names.push_back(m.name);
	return names;
}

}  // namespace forest_slam::core
