#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace ffloc {

// One member of a zip archive, as listed by the central directory (the local headers of
// torch.save() archives carry zero sizes and a data descriptor, so they cannot be trusted).
struct ZipEntry {
  std::string name;
  uint16_t method = 0;  // 0 = stored, 8 = deflate
  uint16_t flags = 0;
  uint64_t compressed_size = 0;
  uint64_t uncompressed_size = 0;
  uint64_t local_header_offset = 0;
};

// The directory of a zip archive held in memory (a memory-mapped file), with zip64 support for
// archives and members beyond 4 GB. Only stored (uncompressed) members can be read, which is
// what torch.save() writes; their bytes are served in place, without copying. Every offset and
// size is checked against the buffer: a damaged archive raises InputError naming `source`.
class ZipReader {
 public:
  ZipReader(const uint8_t* data, uint64_t size, std::string source);

  const std::vector<ZipEntry>& entries() const { return entries_; }
  // nullptr when absent.
  const ZipEntry* find(const std::string& name) const;
  // The member's bytes inside the buffer; InputError when compressed, encrypted or out of
  // bounds.
  const uint8_t* storedData(const ZipEntry& entry) const;

 private:
  [[noreturn]] void fail(const std::string& what) const;
  void readCentralDirectory(uint64_t offset, uint64_t size, uint64_t count);

  const uint8_t* data_;
  uint64_t size_;
  std::string source_;
  std::vector<ZipEntry> entries_;
  std::map<std::string, size_t> index_;
};

}  // namespace ffloc
