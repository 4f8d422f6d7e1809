#include <forest_slam/eval/csv_table.h>
#include <forest_slam/eval/position_track.h>
#include <forest_slam/io/tum.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <stdexcept>

namespace forest_slam::eval
{
namespace
{
bool looksLikeCsv(const std::string& path)
{
	std::ifstream f(path);
	if (!f)
		throw std::runtime_error("cannot open '" + path +
		                         "': " + std::strerror(errno));
	std::string line;
	while (std::getline(f, line))
	{
		const auto b = line.find_first_not_of(" \t\r");
		if (b == std::string::npos || line[b] == '#') continue;
		return line.find(',') != std::string::npos;
	}
	return false;
}
}  // namespace

PositionTrack readPositionTrack(const std::string& path)
{
	PositionTrack track;
	if (!looksLikeCsv(path))
	{
		for (const auto& p : io::readTum(path))
			track.push_back({p.t_s, p.pose.translation()});
		return track;
	}
	const CsvTable csv = CsvTable::read(path);
	const size_t ct = csv.column("t"), cx = csv.column("x"),
	             cy = csv.column("y"), cz = csv.column("z");
	for (size_t r = 0; r < csv.rows(); r++)
	{
		PositionFix fix;
		fix.t_s = csv.number(r, ct);
		fix.p = {csv.number(r, cx), csv.number(r, cy), csv.number(r, cz)};
		if (!track.empty() && fix.t_s < track.back().t_s)
			throw std::runtime_error(csv.where(r, ct) +
			                         ": time goes backwards");
		track.push_back(fix);
	}
	return track;
}

}  // namespace forest_slam::eval
