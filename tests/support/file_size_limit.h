#pragma once
// A file size limit in place of a full disk: while the object lives, writes
// past `bytes` fail with EFBIG (SIGXFSZ, which would kill the test, is
// ignored meanwhile). Shared by the tests of the scratch files' errors.
#include <sys/resource.h>

#include <csignal>

namespace forest_slam::test
{
class FileSizeLimit
{
   public:
	explicit FileSizeLimit(rlim_t bytes)
	{
		ok_ = getrlimit(RLIMIT_FSIZE, &old_) == 0;
		old_handler_ = std::signal(SIGXFSZ, SIG_IGN);
		rlimit small = old_;
		small.rlim_cur = bytes;
		ok_ = ok_ && setrlimit(RLIMIT_FSIZE, &small) == 0;
	}
	~FileSizeLimit()
	{
		setrlimit(RLIMIT_FSIZE, &old_);
		std::signal(SIGXFSZ, old_handler_);
	}
	FileSizeLimit(const FileSizeLimit&) = delete;
	FileSizeLimit& operator=(const FileSizeLimit&) = delete;
	bool ok() const { return ok_; }

   private:
	rlimit old_{};
	void (*old_handler_)(int) = SIG_DFL;
	bool ok_ = false;
};
}  // namespace forest_slam::test
