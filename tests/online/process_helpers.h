#pragma once
// Child processes for the online tests: started with their output in a
// file, waited for with a deadline (a test never hangs), signalled by pid.
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace online_test
{
inline std::string slurp(const std::string& path)
{
	std::ifstream f(path);
	std::stringstream ss;
	ss << f.rdbuf();
	return ss.str();
}

class Child
{
   public:
	/** Runs argv[0] (a path) with stdout+stderr into `log`, cwd = repo root. */
	Child(const std::vector<std::string>& argv, const std::string& log)
	    : log_(log)
	{
		pid_ = ::fork();
		if (pid_ == 0)
		{
			const int fd =
			    ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
			::dup2(fd, 1);
			::dup2(fd, 2);
			if (::chdir(FOREST_SLAM_SOURCE_DIR) != 0) ::_exit(126);
			std::vector<char*> args;
			for (const auto& a : argv)
				args.push_back(const_cast<char*>(a.c_str()));
			args.push_back(nullptr);
			::execv(args[0], args.data());
			::_exit(127);
		}
	}
	~Child()
	{
		if (pid_ > 0 && code_ == kRunning)
		{
			::kill(pid_, SIGKILL);
			::waitpid(pid_, nullptr, 0);
		}
	}
	void signal(int sig) const { ::kill(pid_, sig); }
	/** Exit code, or -1 if it was killed after `timeout_s` (or by a signal). */
	int wait(double timeout_s)
	{
		const auto end = std::chrono::steady_clock::now() +
		                 std::chrono::duration<double>(timeout_s);
		while (code_ == kRunning)
		{
			int st = 0;
			if (::waitpid(pid_, &st, WNOHANG) == pid_)
				code_ = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
			else if (std::chrono::steady_clock::now() > end)
			{
				::kill(pid_, SIGKILL);
				::waitpid(pid_, nullptr, 0);
				code_ = -1;
			}
			else
				std::this_thread::sleep_for(std::chrono::milliseconds(20));
		}
		return code_;
	}
	/** Waits until the output contains `text`; false after `timeout_s` or
	 * if the process ended first. */
	bool waitForOutput(const std::string& text, double timeout_s)
	{
		const auto end = std::chrono::steady_clock::now() +
		                 std::chrono::duration<double>(timeout_s);
		while (std::chrono::steady_clock::now() < end)
		{
			if (output().find(text) != std::string::npos) return true;
			int st = 0;
			if (::waitpid(pid_, &st, WNOHANG) == pid_)
			{
				code_ = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
				return output().find(text) != std::string::npos;
			}
			std::this_thread::sleep_for(std::chrono::milliseconds(20));
		}
		return false;
	}
	std::string output() const { return slurp(log_); }

   private:
	static constexpr int kRunning = -1000;
	pid_t pid_ = -1;
	int code_ = kRunning;
	std::string log_;
};

inline std::string bin(const std::string& name)
{
	return std::string(FOREST_SLAM_BIN_DIR) + "/" + name;
}

inline std::string tempDir(const std::string& name)
{
	const auto d = std::filesystem::temp_directory_path() /
	               ("fs_online_" + std::to_string(::getpid()) + "_" + name);
	std::filesystem::remove_all(d);
	std::filesystem::create_directories(d);
	return d.string();
}

}  // namespace online_test
