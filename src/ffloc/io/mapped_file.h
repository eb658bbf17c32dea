#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>

namespace ffloc {

// How a MappedFile holds the file's bytes.
enum class FileMapping {
  // The file itself, mapped: nothing is copied and the kernel pages in only what is touched, but
  // the bytes are the file's as it is now, so a file written over or cut short in place changes
  // them or ends the process (SIGBUS) at the next touch.
  kFile,
  // A copy taken when it opens, in memory of its own (a memfd, mapped): what a process that keeps
  // the file open while others may write it in place (a server's maps) must hold.
  kSnapshot,
};

// A whole file mapped read-only into memory. Weights files are large (the official DUSt3R
// checkpoint is 2.2 GB), so tensors are served as views into the mapping instead of copies; the
// kernel pages in only what is touched.
class MappedFile {
 public:
  // InputError naming the file when it is missing, not a regular file or cannot be mapped, or,
  // for a snapshot, when it changed while it was copied. An empty file maps to size() == 0 and a
  // null data().
  explicit MappedFile(const std::filesystem::path& path, FileMapping mapping = FileMapping::kFile);
  ~MappedFile();
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;

  const std::filesystem::path& path() const { return path_; }
  const uint8_t* data() const { return data_; }
  std::size_t size() const { return size_; }

 private:
  std::filesystem::path path_;
  const uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
};

// Drops the pages of [begin, begin + size), a range of a MappedFile, from the process's resident
// memory: they stay in the kernel's page cache (a snapshot's in its memfd) and come back, without
// a disk read while they are cached, on the next access. For passes over a whole mapping (a checksum)
// that would otherwise leave all of it counted in the process's RSS. The range is widened to
// whole pages, which a read-only file mapping always spans.
void releaseMappedPages(const uint8_t* begin, std::size_t size);

}  // namespace ffloc
