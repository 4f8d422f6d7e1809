#include <forest_slam/core/atomic_file.h>

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace forest_slam::core
{
std::string tempPathFor(const std::string& path)
{
	return path + ".tmp." + std::to_string(::getpid());
}

namespace
{
void fsyncPath(const std::string& p)
{
	const int fd = ::open(p.c_str(), O_RDONLY);
	if (fd >= 0)
	{
		::fsync(fd);
		::close(fd);
	}
}
}  // namespace

void commitTempFile(const std::string& path)
{
	const std::string tmp = tempPathFor(path);
	fsyncPath(tmp);
	if (std::rename(tmp.c_str(), path.c_str()) != 0)
		throw std::runtime_error(
			"cannot rename '" + tmp + "' to '" + path +
			"': " + std::strerror(errno));
	const auto parent = std::filesystem::path(path).parent_path();
	fsyncPath(parent.empty() ? "." : parent.string());
}

AtomicFileWriter::AtomicFileWriter(const std::string& path, bool binary)
	: path_(path), tmp_path_(tempPathFor(path))
{
	out_.open(tmp_path_, binary ? std::ios::out | std::ios::binary
								: std::ios::out);
	if (!out_)
		throw std::runtime_error(
			"cannot create '" + tmp_path_ + "' (for '" + path_ +
			"'): " + std::strerror(errno));
}

AtomicFileWriter::~AtomicFileWriter()
{
	if (!committed_)
	{
		out_.close();
		std::remove(tmp_path_.c_str());
	}
}

std::vector<std::string> removeStaleTempFiles(const std::string& dir)
{
	std::vector<std::string> removed;
	std::error_code ec;
	for (const auto& e : std::filesystem::directory_iterator(dir, ec))
	{
		const std::string name = e.path().filename().string();
		const auto at = name.rfind(".tmp.");
		if (at == std::string::npos || !e.is_regular_file(ec)) continue;
		const std::string digits = name.substr(at + 5);
		if (digits.empty() ||
		    digits.find_first_not_of("0123456789") != std::string::npos)
			continue;
		const long pid = std::strtol(digits.c_str(), nullptr, 10);
		if (pid <= 0) continue;
		// Alive (or another user's): not ours to remove.
		if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM) continue;
		if (std::filesystem::remove(e.path(), ec))
			removed.push_back(e.path().string());
	}
	return removed;
}

void AtomicFileWriter::commit()
{
	out_.flush();
	if (!out_)
		throw std::runtime_error("write error on '" + tmp_path_ + "'");
	out_.close();
	commitTempFile(path_);
	committed_ = true;
}

void writeFileAtomically(const std::string& path,
						 const std::function<void(std::ostream&)>& fill,
						 bool binary)
{
	AtomicFileWriter w(path, binary);
	fill(w.stream());
	w.commit();
}

void ensureDirectory(const std::string& dir)
{
	std::error_code ec;
	std::filesystem::create_directories(dir, ec);
	if (ec || !std::filesystem::is_directory(dir))
		throw std::runtime_error(
			"cannot create output directory '" + dir + "': " + ec.message());
}

}  // namespace forest_slam::core
