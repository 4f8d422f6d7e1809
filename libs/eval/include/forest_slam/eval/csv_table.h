#pragma once
// Comma-separated files with a header row, columns looked up by name, so the
// evaluator accepts any extra columns a producer adds. Every error names
// file:line:column and what was expected.
#include <optional>
#include <string>
#include <vector>

namespace forest_slam::eval
{
class CsvTable
{
   public:
	/** The header is the first line that is neither blank nor a '#' comment;
	 * later blank and '#' lines are skipped. Fields are trimmed; a field
	 * wrapped in double quotes loses the quotes (no embedded commas).
	 * Throws std::runtime_error naming file and line if the file cannot be
	 * read, has no header, repeats a column name or has a row whose field
	 * count differs from the header's. */
	static CsvTable read(const std::string& path);

	const std::string& path() const { return path_; }
	const std::vector<std::string>& header() const { return header_; }
	size_t rows() const { return cells_.size(); }
	/** 1-based line number of a data row in the file. */
	size_t lineOf(size_t row) const { return lines_[row]; }

	/** Column index by exact (trimmed) name, case-insensitive. */
	std::optional<size_t> findColumn(const std::string& name) const;
	/** Same, but throws naming the file, the header line and the columns
	 * that were found. */
	size_t column(const std::string& name) const;

	const std::string& cell(size_t row, size_t col) const
	{
		return cells_[row][col];
	}
	/** Finite number, or throws "file:line:column (name): expected ...". */
	double number(size_t row, size_t col) const;
	/** 0/1/true/false/yes/no (case-insensitive), or throws like number(). */
	bool boolean(size_t row, size_t col) const;
	/** "file:line:column (name)" for error messages of callers. */
	std::string where(size_t row, size_t col) const;

   private:
	std::string path_;
	size_t header_line_ = 0;
	std::vector<std::string> header_;
	std::vector<std::vector<std::string>> cells_;
	std::vector<size_t> lines_;
};

/** Strict decimal parse of a whole string (leading/trailing spaces allowed);
 * nullopt if anything else is present or the value is not finite. */
std::optional<double> parseFiniteNumber(const std::string& text);

}  // namespace forest_slam::eval
