#pragma once
// Outputs are written to "<path>.tmp.<pid>" and renamed over <path> only once
// complete, so a crash or kill -9 never leaves a half-written file behind and
// never destroys the previous version.
#include <fstream>
#include <functional>
#include <string>
#include <vector>

namespace forest_slam::core
{
class AtomicFileWriter
{
   public:
	/** Opens the temporary file; throws std::runtime_error naming the path. */
	explicit AtomicFileWriter(const std::string& path, bool binary = false);
	/** Removes the temporary file unless commit() succeeded. */
	~AtomicFileWriter();
	AtomicFileWriter(const AtomicFileWriter&) = delete;
	AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;

	std::ostream& stream() { return out_; }
	const std::string& tempPath() const { return tmp_path_; }
	const std::string& finalPath() const { return path_; }

	/** Flushes, fsyncs and renames into place; throws on any I/O error. */
	void commit();

   private:
	std::string path_, tmp_path_;
	std::ofstream out_;
	bool committed_ = false;
};

/** Convenience: writes a whole file through `fill` atomically. */
void writeFileAtomically(const std::string& path,
						 const std::function<void(std::ostream&)>& fill,
						 bool binary = false);

/** Temp name for a writer that must own the file itself (e.g. a gzip stream):
 * write to tempPathFor(p), then commitTempFile(p). */
std::string tempPathFor(const std::string& path);
void commitTempFile(const std::string& path);

/** Removes the temporary files ("<name>.tmp.<pid>") that a process killed
 * while writing (kill -9, power loss) left in `dir`: those whose process no
 * longer runs. Returns the paths removed. The final files were never
 * touched by such a writer, so nothing else needs repair. */
std::vector<std::string> removeStaleTempFiles(const std::string& dir);

/** Creates a directory (and parents); throws naming the path on failure. */
void ensureDirectory(const std::string& dir);

}  // namespace forest_slam::core
