#include <forest_slam/eval/csv_table.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <stdexcept>

namespace forest_slam::eval
{
namespace
{
std::string trim(const std::string& s)
{
	const auto b = s.find_first_not_of(" \t\r\n");
	if (b == std::string::npos) return {};
	const auto e = s.find_last_not_of(" \t\r\n");
	return s.substr(b, e - b + 1);
}

std::string lower(std::string s)
{
	std::transform(s.begin(), s.end(), s.begin(),
	               [](unsigned char c) { return std::tolower(c); });
	return s;
}

std::vector<std::string> splitFields(const std::string& line)
{
	std::vector<std::string> out;
	size_t start = 0;
	while (true)
	{
		const auto comma = line.find(',', start);
		std::string f = trim(line.substr(start, comma == std::string::npos
		                                            ? std::string::npos
		                                            : comma - start));
		if (f.size() >= 2 && f.front() == '"' && f.back() == '"')
			f = trim(f.substr(1, f.size() - 2));
		out.push_back(f);
		if (comma == std::string::npos) break;
		start = comma + 1;
	}
	return out;
}

std::string joined(const std::vector<std::string>& v)
{
	std::string s;
	for (const auto& x : v) s += (s.empty() ? "" : ",") + x;
	return s;
}
}  // namespace

std::optional<double> parseFiniteNumber(const std::string& text)
{
	const std::string t = trim(text);
	if (t.empty()) return std::nullopt;
	errno = 0;
	char* end = nullptr;
	const double v = std::strtod(t.c_str(), &end);
	if (end != t.c_str() + t.size() || errno == ERANGE || !std::isfinite(v))
		return std::nullopt;
	return v;
}

CsvTable CsvTable::read(const std::string& path)
{
	std::ifstream f(path);
	if (!f)
		throw std::runtime_error("cannot open '" + path +
		                         "': " + std::strerror(errno));
	CsvTable t;
	t.path_ = path;
	std::string line;
	size_t lineno = 0;
	while (std::getline(f, line))
	{
		lineno++;
		const std::string tl = trim(line);
		if (tl.empty() || tl[0] == '#') continue;
		auto fields = splitFields(line);
		if (t.header_.empty())
		{
			t.header_line_ = lineno;
			for (size_t i = 0; i < fields.size(); i++)
			{
				if (fields[i].empty())
					throw std::runtime_error(path + ":" +
					                         std::to_string(lineno) + ":" +
					                         std::to_string(i + 1) +
					                         ": empty column name in header");
				for (size_t j = 0; j < i; j++)
					if (lower(fields[j]) == lower(fields[i]))
						throw std::runtime_error(
						    path + ":" + std::to_string(lineno) + ":" +
						    std::to_string(i + 1) + ": column '" + fields[i] +
						    "' appears twice in the header");
			}
			t.header_ = std::move(fields);
			continue;
		}
		if (fields.size() != t.header_.size())
			throw std::runtime_error(
			    path + ":" + std::to_string(lineno) + ": expected " +
			    std::to_string(t.header_.size()) + " comma-separated fields (" +
			    joined(t.header_) + "), got " + std::to_string(fields.size()));
		t.cells_.push_back(std::move(fields));
		t.lines_.push_back(lineno);
	}
	if (f.bad()) throw std::runtime_error("error reading '" + path + "'");
	if (t.header_.empty())
		throw std::runtime_error(path +
		                         ": empty file, expected a CSV header line");
	return t;
}

std::optional<size_t> CsvTable::findColumn(const std::string& name) const
{
	for (size_t i = 0; i < header_.size(); i++)
		if (lower(header_[i]) == lower(name)) return i;
	return std::nullopt;
}

size_t CsvTable::column(const std::string& name) const
{
	if (auto c = findColumn(name)) return *c;
	throw std::runtime_error(path_ + ":" + std::to_string(header_line_) +
	                         ": header has no column '" + name +
	                         "' (found: " + joined(header_) + ")");
}

std::string CsvTable::where(size_t row, size_t col) const
{
	return path_ + ":" + std::to_string(lines_[row]) + ":" +
	       std::to_string(col + 1) + " (" + header_[col] + ")";
}

double CsvTable::number(size_t row, size_t col) const
{
	if (auto v = parseFiniteNumber(cells_[row][col])) return *v;
	throw std::runtime_error(where(row, col) +
	                         ": expected a finite number, got '" +
	                         cells_[row][col] + "'");
}

bool CsvTable::boolean(size_t row, size_t col) const
{
	const std::string v = lower(cells_[row][col]);
	if (v == "1" || v == "true" || v == "yes") return true;
	if (v == "0" || v == "false" || v == "no") return false;
	throw std::runtime_error(where(row, col) +
	                         ": expected 0/1/true/false, got '" +
	                         cells_[row][col] + "'");
}

}  // namespace forest_slam::eval
