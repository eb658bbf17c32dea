#include "ffloc/io/mapped_file.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/sendfile.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "ffloc/core/error.h"
#include "ffloc/core/file_stamp.h"

namespace ffloc {

namespace {

// A memfd holding the first `size` bytes of `fd`, or -1 with errno set; `changed` when the file's
// size or modification time moved while it was copied (a writer in place: the copy may be torn).
int snapshotOf(int fd, const struct stat& before, bool& changed) {
  const int copy = ::memfd_create("ffloc-snapshot", MFD_CLOEXEC);
  if (copy < 0) return -1;
  const auto size = static_cast<std::size_t>(before.st_size);
  off_t offset = 0;
  while (static_cast<std::size_t>(offset) < size) {
    const ssize_t sent = ::sendfile(copy, fd, &offset, size - static_cast<std::size_t>(offset));
    if (sent < 0 && errno == EINTR) continue;
    if (sent <= 0) {
      changed = sent == 0;  // the file ended early: cut short while it was copied
      const int error = errno;
      ::close(copy);
      errno = error;
      return -1;
    }
  }
  struct stat after {};
  changed = ::fstat(fd, &after) != 0 || fileStampOf(after) != fileStampOf(before);
  return copy;
}

}  // namespace

MappedFile::MappedFile(const std::filesystem::path& path, FileMapping mapping) : path_(path) {
  // O_NONBLOCK so that a FIFO given by mistake is rejected below instead of blocking the open.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) throwInputError(path.string(), 0, std::string("cannot open: ") + std::strerror(errno));
  struct stat info {};
  if (::fstat(fd, &info) != 0 || !S_ISREG(info.st_mode)) {
    ::close(fd);
    throwInputError(path.string(), 0, "not a regular file");
  }
  size_ = static_cast<std::size_t>(info.st_size);
  if (size_ == 0) {
    ::close(fd);
    return;
  }
  int source = fd;
  if (mapping == FileMapping::kSnapshot) {
    bool changed = false;
    source = snapshotOf(fd, info, changed);
    const int error = errno;
    ::close(fd);
    if (changed) {
      if (source >= 0) ::close(source);
      throwInputError(path.string(), 0, "changed while it was read (written in place?); read it again once written");
    }
    if (source < 0) throwInputError(path.string(), 0, std::string("cannot copy into memory: ") + std::strerror(error));
  }
  void* bytes = ::mmap(nullptr, size_, PROT_READ, mapping == FileMapping::kSnapshot ? MAP_SHARED : MAP_PRIVATE, source, 0);
  const int error = errno;
  // The mapping stays valid after the descriptor is closed.
  ::close(source);
  if (bytes == MAP_FAILED) throwInputError(path.string(), 0, std::string("cannot map into memory: ") + std::strerror(error));
  data_ = static_cast<const uint8_t*>(bytes);
}

MappedFile::~MappedFile() {
  if (data_ != nullptr) ::munmap(const_cast<uint8_t*>(data_), size_);
}

void releaseMappedPages(const uint8_t* begin, std::size_t size) {
  if (size == 0) return;
  const auto page = static_cast<uintptr_t>(::sysconf(_SC_PAGESIZE));
  const uintptr_t first = reinterpret_cast<uintptr_t>(begin) / page * page;
  const uintptr_t end = (reinterpret_cast<uintptr_t>(begin) + size + page - 1) / page * page;
  // Advice only: on failure the pages merely stay resident.
  ::madvise(reinterpret_cast<void*>(first), end - first, MADV_DONTNEED);
}

}  // namespace ffloc
