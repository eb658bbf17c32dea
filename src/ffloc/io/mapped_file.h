#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>

namespace ffloc {

// A whole file mapped read-only into memory. Weights files are large (the official DUSt3R
// checkpoint is 2.2 GB), so tensors are served as views into the mapping instead of copies; the
// kernel pages in only what is touched.
class MappedFile {
 public:
  // InputError naming the file when it is missing, not a regular file or cannot be mapped. An
  // empty file maps to size() == 0 and a null data().
  explicit MappedFile(const std::filesystem::path& path);
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

// Drops the pages of [begin, begin + size), a range of a read-only file mapping, from the
// process's resident memory: they stay in the kernel's page cache and come back, without a disk
// read while they are cached, on the next access. For passes over a whole mapping (a checksum)
// that would otherwise leave all of it counted in the process's RSS. The range is widened to
// whole pages, which a read-only file mapping always spans.
void releaseMappedPages(const uint8_t* begin, std::size_t size);

}  // namespace ffloc
