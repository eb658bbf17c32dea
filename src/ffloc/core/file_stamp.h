#pragma once

#include <sys/stat.h>

#include <cstdint>
#include <filesystem>
#include <optional>

namespace ffloc {

// What tells one version of a file from another without reading it: which file it is (an atomic
// rename brings a new inode), its size and its modification time.
struct FileStamp {
  dev_t device = 0;
  ino_t inode = 0;
  off_t size = -1;
  int64_t modified_ns = 0;
  bool operator==(const FileStamp& other) const {
    return device == other.device && inode == other.inode && size == other.size && modified_ns == other.modified_ns;
  }
  bool operator!=(const FileStamp& other) const { return !(*this == other); }
};

inline FileStamp fileStampOf(const struct stat& info) {
  return {info.st_dev, info.st_ino, info.st_size,
          static_cast<int64_t>(info.st_mtim.tv_sec) * 1000000000 + info.st_mtim.tv_nsec};
}

// nullopt when the file cannot be looked at (missing, mid-replacement).
inline std::optional<FileStamp> fileStampOf(const std::filesystem::path& path) {
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0) return std::nullopt;
  return fileStampOf(info);
}

}  // namespace ffloc
