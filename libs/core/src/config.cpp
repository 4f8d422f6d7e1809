#include <forest_slam/core/config.h>

#include <mrpt/system/string_utils.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace forest_slam::core
{
namespace
{
std::string lower(std::string s)
{
	std::transform(s.begin(), s.end(), s.begin(),
				   [](unsigned char c) { return std::tolower(c); });
	return s;
}
std::string trim(const std::string& s)
{
	const auto b = s.find_first_not_of(" \t\r\n");
	if (b == std::string::npos) return {};
	const auto e = s.find_last_not_of(" \t\r\n");
	return s.substr(b, e - b + 1);
}
}  // namespace

TrackedConfig::TrackedConfig(std::string content, std::string origin)
	: mem_(content), origin_(std::move(origin))
{
}

TrackedConfig::TrackedConfig(const TrackedConfig& o)
	: mrpt::config::CConfigFileBase(),
	  mem_(o.mem_.getContent()),
	  origin_(o.origin_),
	  read_keys_(o.read_keys_),
	  accepted_sections_(o.accepted_sections_)
{
}

TrackedConfig& TrackedConfig::operator=(const TrackedConfig& o)
{
	if (this != &o)
	{
		mem_.setContent(o.mem_.getContent());
		origin_ = o.origin_;
		read_keys_ = o.read_keys_;
		accepted_sections_ = o.accepted_sections_;
	}
	return *this;
}

TrackedConfig::~TrackedConfig() = default;

TrackedConfig TrackedConfig::fromFile(const std::string& path)
{
	std::ifstream f(path);
	if (!f)
		throw ConfigError("cannot open config file '" + path + "'");
	std::ostringstream text;
	text << f.rdbuf();
	if (f.bad())
		throw ConfigError("cannot read config file '" + path + "'");
	return fromText(text.str(), path);
}

TrackedConfig TrackedConfig::fromText(
	const std::string& text, const std::string& origin)
{
	// MRPT's INI preprocessor ($env{}, $eval{}, @include) throws plain
	// std::runtime_error naming only a line (found by fuzz_ini).
	try
	{
		return TrackedConfig(text, origin);
	}
	catch (const std::exception& e)
	{
		throw ConfigError(
			"cannot parse config file '" + origin + "': " + e.what());
	}
}

void TrackedConfig::getAllSections(std::vector<std::string>& sections) const
{
	mem_.getAllSections(sections);
}
void TrackedConfig::getAllKeys(
	const std::string& section, std::vector<std::string>& keys) const
{
	mem_.getAllKeys(section, keys);
}
void TrackedConfig::clear()
{
	mem_.clear();
	read_keys_.clear();
}

void TrackedConfig::acceptSection(const std::string& section)
{
	accepted_sections_.insert(lower(section));
}

std::string TrackedConfig::content() const { return mem_.getContent(); }

void TrackedConfig::writeString(
	const std::string& section, const std::string& name, const std::string& str)
{
	mem_.write(section, name, str);
}

std::string TrackedConfig::readString(
	const std::string& section, const std::string& name,
	const std::string& defaultStr, bool failIfNotFound) const
{
	read_keys_.emplace(lower(section), lower(name));
	if (!mem_.keyExists(section, name))
	{
		if (failIfNotFound)
			throw ConfigError(
				origin_ + ": missing required key '" + name + "' in section [" +
				section + "]");
		return defaultStr;
	}
	// Strip trailing "// comment" like MRPT's reader does.
	std::string v = mem_.read_string(section, name, defaultStr);
	return trim(v);
}

void TrackedConfig::checkNoUnknownKeys() const
{
	std::vector<std::string> sections;
	mem_.getAllSections(sections);
	for (const auto& s : sections)
	{
		const auto ls = lower(s);
		if (accepted_sections_.count(ls)) continue;
		std::vector<std::string> keys;
		mem_.getAllKeys(s, keys);
		bool section_known = false;
		for (const auto& k : read_keys_)
			if (k.first == ls) section_known = true;
		for (const auto& k : keys)
		{
			if (read_keys_.count({ls, lower(k)})) continue;
			if (!section_known)
				throw ConfigError(
					origin_ + ": unknown section [" + s + "] (key '" + k +
					"'): no module reads this section");
			throw ConfigError(
				origin_ + ": unknown key '" + k + "' in section [" + s +
				"]: no module reads it (typo? see doc/user-guide.md)");
		}
	}
}

std::string configOrigin(const mrpt::config::CConfigFileBase& cfg)
{
	if (auto* t = dynamic_cast<const TrackedConfig*>(&cfg)) return t->origin();
	return "<config>";
}

template <>
std::string parseConfigValue<std::string>(
	const std::string& text, const std::string&)
{
	return text;
}

template <>
bool parseConfigValue<bool>(const std::string& text, const std::string& where)
{
	const auto t = lower(text);
	if (t == "1" || t == "true" || t == "yes" || t == "on") return true;
	if (t == "0" || t == "false" || t == "no" || t == "off") return false;
	throw ConfigError(
		where + ": expected a boolean (true/false/1/0), got '" + text + "'");
}

template <>
double parseConfigValue<double>(const std::string& text, const std::string& where)
{
	const char* b = text.c_str();
	char* e = nullptr;
	errno = 0;
	const double v = std::strtod(b, &e);
	if (text.empty() || e == b || *e != '\0' || errno == ERANGE ||
		!std::isfinite(v))
		throw ConfigError(
			where + ": expected a finite number, got '" + text + "'");
	return v;
}

template <>
float parseConfigValue<float>(const std::string& text, const std::string& where)
{
	return static_cast<float>(parseConfigValue<double>(text, where));
}

template <>
long long parseConfigValue<long long>(
	const std::string& text, const std::string& where)
{
	const char* b = text.c_str();
	char* e = nullptr;
	errno = 0;
	const long long v = std::strtoll(b, &e, 10);
	if (text.empty() || e == b || *e != '\0' || errno == ERANGE)
		throw ConfigError(
			where + ": expected an integer, got '" + text + "'");
	return v;
}

template <>
int parseConfigValue<int>(const std::string& text, const std::string& where)
{
	const long long v = parseConfigValue<long long>(text, where);
	if (v < INT32_MIN || v > INT32_MAX)
		throw ConfigError(where + ": integer out of range: '" + text + "'");
	return static_cast<int>(v);
}

template <>
unsigned parseConfigValue<unsigned>(
	const std::string& text, const std::string& where)
{
	const long long v = parseConfigValue<long long>(text, where);
	if (v < 0 || v > UINT32_MAX)
		throw ConfigError(
			where + ": expected a non-negative integer, got '" + text + "'");
	return static_cast<unsigned>(v);
}

template <>
uint64_t parseConfigValue<uint64_t>(
	const std::string& text, const std::string& where)
{
	const long long v = parseConfigValue<long long>(text, where);
	if (v < 0)
		throw ConfigError(
			where + ": expected a non-negative integer, got '" + text + "'");
	return static_cast<uint64_t>(v);
}

template <>
std::vector<double> parseConfigValue<std::vector<double>>(
	const std::string& text, const std::string& where)
{
	std::vector<double> out;
	std::string cleaned = text;
	for (char& c : cleaned)
		if (c == ',' || c == '[' || c == ']' || c == ';') c = ' ';
	std::istringstream is(cleaned);
	std::string tok;
	while (is >> tok) out.push_back(parseConfigValue<double>(tok, where));
	return out;
}

template <typename T>
void loadOption(const mrpt::config::CConfigFileBase& cfg,
				const std::string& section, const std::string& key, T& value)
{
	const std::string raw = cfg.read_string(section, key, "\x01");
	if (raw == "\x01") return;	// absent: keep the default
	const std::string where =
		configOrigin(cfg) + ": [" + section + "] " + key;
	value = parseConfigValue<T>(trim(raw), where);
}

template void loadOption<std::string>(
	const mrpt::config::CConfigFileBase&, const std::string&,
	const std::string&, std::string&);
template void loadOption<bool>(const mrpt::config::CConfigFileBase&,
							   const std::string&, const std::string&, bool&);
template void loadOption<double>(const mrpt::config::CConfigFileBase&,
								 const std::string&, const std::string&,
								 double&);
template void loadOption<float>(const mrpt::config::CConfigFileBase&,
								const std::string&, const std::string&, float&);
template void loadOption<int>(const mrpt::config::CConfigFileBase&,
							  const std::string&, const std::string&, int&);
template void loadOption<unsigned>(const mrpt::config::CConfigFileBase&,
								   const std::string&, const std::string&,
								   unsigned&);
template void loadOption<uint64_t>(const mrpt::config::CConfigFileBase&,
								   const std::string&, const std::string&,
								   uint64_t&);
template void loadOption<std::vector<double>>(
	const mrpt::config::CConfigFileBase&, const std::string&,
	const std::string&, std::vector<double>&);

}  // namespace forest_slam::core
