#include "ffloc/core/writer_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <thread>

#include "ffloc/core/error.h"
#include "ffloc/core/progress.h"

namespace ffloc {

std::filesystem::path writerLockFile(const std::filesystem::path& target) {
  const std::filesystem::path folder = target.has_parent_path() ? target.parent_path() : ".";
  return folder / ("." + target.filename().string() + ".lock");
}

WriterLock::WriterLock(const std::filesystem::path& target, const std::function<void()>& on_wait) {
  if (!target.has_filename()) throwInputError(target.string(), 0, "is a folder, not a file to write");
  const std::filesystem::path lock_file = writerLockFile(target);
  descriptor_ = ::open(lock_file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
  if (descriptor_ < 0) {
    const int error = errno;
    std::error_code unreachable;
    if (!std::filesystem::is_directory(lock_file.parent_path(), unreachable))
      throwInputError(target.string(), 0, "output folder does not exist");
    throwInputError(target.string(), 0, std::string("cannot make files in its folder: ") + std::strerror(error));
  }
  if (::flock(descriptor_, LOCK_EX | LOCK_NB) == 0) return;
  // The constructor that throws runs no destructor: the descriptor is closed here.
  try {
    if (errno == EWOULDBLOCK && on_wait) on_wait();
    // Asked again every tenth of a second rather than blocked on: a wait blocked in flock heard
    // no Ctrl-C from Python, whose handler runs only when the library asks (StopCheck).
    while (::flock(descriptor_, LOCK_EX | LOCK_NB) != 0) {
      const int error = errno;
      if (error != EWOULDBLOCK && error != EINTR)
        throwInputError(lock_file.string(), 0, std::string("cannot lock: ") + std::strerror(error));
      stopIfRequested("waiting for " + lock_file.string());
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  } catch (...) {
    ::close(descriptor_);
    throw;
  }
}

WriterLock::~WriterLock() { ::close(descriptor_); }

}  // namespace ffloc
