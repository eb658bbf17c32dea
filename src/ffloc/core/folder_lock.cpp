#include "ffloc/core/folder_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "ffloc/core/error.h"

namespace ffloc {

FolderLock::FolderLock(const std::filesystem::path& folder, const std::function<void()>& on_wait) {
  descriptor_ = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (descriptor_ < 0) throwInputError(folder.string(), 0, std::string("cannot open the folder: ") + std::strerror(errno));
  if (::flock(descriptor_, LOCK_EX | LOCK_NB) == 0) return;
  if (errno == EWOULDBLOCK && on_wait) on_wait();
  while (::flock(descriptor_, LOCK_EX) != 0) {
    if (errno == EINTR) continue;
    const int error = errno;
    ::close(descriptor_);
    throwInputError(folder.string(), 0, std::string("cannot lock the folder: ") + std::strerror(error));
  }
}

FolderLock::~FolderLock() { ::close(descriptor_); }

}  // namespace ffloc
