#pragma once
// Strict INI configuration on top of MRPT's config classes.
//
// MRPT silently ignores keys nobody reads; a typo then costs a user hours.
// TrackedConfig remembers every (section, key) that a module read, so that
// after all modules loaded their options, checkNoUnknownKeys() can report the
// first key that no module knows, naming file, section and key.
#include <mrpt/config/CConfigFileBase.h>
#include <mrpt/config/CConfigFileMemory.h>

#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace forest_slam::core
{
/** Any configuration problem: unknown key, unparsable value, missing file. */
class ConfigError : public std::runtime_error
{
   public:
	using std::runtime_error::runtime_error;
};

class TrackedConfig : public mrpt::config::CConfigFileBase
{
   public:
	/** Loads an INI file; throws ConfigError if it cannot be read. */
	static TrackedConfig fromFile(const std::string& path);
	/** INI text held in memory; `origin` names it in error messages. */
	static TrackedConfig fromText(
		const std::string& text, const std::string& origin = "<text>");

	TrackedConfig(const TrackedConfig& o);
	TrackedConfig& operator=(const TrackedConfig& o);
	~TrackedConfig() override;

	const std::string& origin() const { return origin_; }

	void getAllSections(std::vector<std::string>& sections) const override;
	void getAllKeys(const std::string& section,
					std::vector<std::string>& keys) const override;
	void clear() override;

	/** Marks a whole section as owned by someone else (e.g. MRPT's own map
	 * definitions, whose keys we do not enumerate). */
	void acceptSection(const std::string& section);

	/** Throws ConfigError naming origin, section and key of the first key in
	 * the file that was never read. Sections are matched case-insensitively
	 * like MRPT does. */
	void checkNoUnknownKeys() const;

	/** The raw text (for "config --dump" and scenario.ini copies). */
	std::string content() const;

   protected:
	void writeString(const std::string& section, const std::string& name,
					 const std::string& str) override;
	std::string readString(const std::string& section, const std::string& name,
						   const std::string& defaultStr,
						   bool failIfNotFound = false) const override;

   private:
	TrackedConfig(std::string content, std::string origin);
	mrpt::config::CConfigFileMemory mem_;
	std::string origin_;
	mutable std::set<std::pair<std::string, std::string>> read_keys_;
	std::set<std::string> accepted_sections_;
};

/** Parses `text` as a value of type T or throws ConfigError with context. */
template <typename T>
T parseConfigValue(const std::string& text, const std::string& where);

/** Reads `key` from `section` into `value` (kept as default if absent);
 * throws ConfigError naming origin/section/key if the text does not parse. */
template <typename T>
void loadOption(const mrpt::config::CConfigFileBase& cfg,
				const std::string& section, const std::string& key, T& value);

/** Helper for option structs: `FS_LOAD(c, s, voxel_size_m);` */
#define FS_LOAD(cfg, section, field) \
	::forest_slam::core::loadOption(cfg, section, #field, field)

/** Where a value came from, for error messages. */
std::string configOrigin(const mrpt::config::CConfigFileBase& cfg);

}  // namespace forest_slam::core
