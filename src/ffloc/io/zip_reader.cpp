#include "ffloc/io/zip_reader.h"

#include "ffloc/core/error.h"

namespace ffloc {
namespace {

constexpr uint32_t kLocalHeaderSignature = 0x04034b50;
constexpr uint32_t kCentralHeaderSignature = 0x02014b50;
constexpr uint32_t kEndSignature = 0x06054b50;
constexpr uint32_t kZip64EndSignature = 0x06064b50;
constexpr uint32_t kZip64LocatorSignature = 0x07064b50;
constexpr uint16_t kZip64ExtraId = 0x0001;
constexpr uint64_t kEndSize = 22;
constexpr uint64_t kZip64LocatorSize = 20;
constexpr uint64_t kZip64EndSize = 56;
constexpr uint64_t kCentralHeaderSize = 46;
constexpr uint64_t kLocalHeaderSize = 30;

uint64_t readLe(const uint8_t* bytes, int count) {
  uint64_t value = 0;
  for (int i = count - 1; i >= 0; --i) value = (value << 8) | bytes[i];
  return value;
}

}  // namespace

ZipReader::ZipReader(const uint8_t* data, uint64_t size, std::string source)
    : data_(data), size_(size), source_(std::move(source)) {
  if (size_ < kEndSize) fail("too short for a zip archive (" + std::to_string(size_) + " bytes)");
  // The end record sits in the last 22 + 65535 (comment) bytes; search backwards.
  const uint64_t lowest = size_ > kEndSize + 0xffff ? size_ - kEndSize - 0xffff : 0;
  uint64_t end = size_ - kEndSize;
  while (true) {
    if (readLe(data_ + end, 4) == kEndSignature &&
        end + kEndSize + readLe(data_ + end + 20, 2) <= size_) {
      break;
    }
    if (end == lowest) fail("no zip end-of-central-directory record; truncated or not a zip file");
    --end;
  }
  uint64_t count = readLe(data_ + end + 10, 2);
  uint64_t directory_size = readLe(data_ + end + 12, 4);
  uint64_t directory_offset = readLe(data_ + end + 16, 4);
  if (count == 0xffff || directory_size == 0xffffffff || directory_offset == 0xffffffff) {
    if (end < kZip64LocatorSize ||
        readLe(data_ + end - kZip64LocatorSize, 4) != kZip64LocatorSignature) {
      fail("zip64 end-of-central-directory locator missing");
    }
    const uint64_t record = readLe(data_ + end - kZip64LocatorSize + 8, 8);
    if (record > size_ || size_ - record < kZip64EndSize ||
        readLe(data_ + record, 4) != kZip64EndSignature) {
      fail("zip64 end-of-central-directory record missing or out of bounds");
    }
    count = readLe(data_ + record + 32, 8);
    directory_size = readLe(data_ + record + 40, 8);
    directory_offset = readLe(data_ + record + 48, 8);
  }
  if (directory_offset > size_ || directory_size > size_ - directory_offset) {
    fail("central directory [" + std::to_string(directory_offset) + ", +" +
         std::to_string(directory_size) + ") lies outside the file (" + std::to_string(size_) +
         " bytes)");
  }
  readCentralDirectory(directory_offset, directory_size, count);
}

void ZipReader::readCentralDirectory(uint64_t offset, uint64_t size, uint64_t count) {
  // The count is untrusted: it only bounds the loop, each header is checked as it is read.
  if (count > size / kCentralHeaderSize) {
    fail("central directory claims " + std::to_string(count) + " entries in " +
         std::to_string(size) + " bytes");
  }
  const uint64_t end = offset + size;
  uint64_t at = offset;
  for (uint64_t i = 0; i < count; ++i) {
    const std::string where = "central directory entry " + std::to_string(i);
    if (end - at < kCentralHeaderSize || readLe(data_ + at, 4) != kCentralHeaderSignature) {
      fail(where + ": bad signature or truncated");
    }
    const uint8_t* header = data_ + at;
    ZipEntry entry;
    entry.flags = static_cast<uint16_t>(readLe(header + 8, 2));
    entry.method = static_cast<uint16_t>(readLe(header + 10, 2));
    entry.compressed_size = readLe(header + 20, 4);
    entry.uncompressed_size = readLe(header + 24, 4);
    const uint64_t name_length = readLe(header + 28, 2);
    const uint64_t extra_length = readLe(header + 30, 2);
    const uint64_t comment_length = readLe(header + 32, 2);
    entry.local_header_offset = readLe(header + 42, 4);
    const uint64_t record_size = kCentralHeaderSize + name_length + extra_length + comment_length;
    if (end - at < record_size) fail(where + ": name or extra field runs past the directory");
    entry.name.assign(reinterpret_cast<const char*>(header + kCentralHeaderSize), name_length);

    // Zip64 extended information: only the fields whose 32-bit slot is saturated are present,
    // in this order.
    const uint8_t* extra = header + kCentralHeaderSize + name_length;
    uint64_t extra_at = 0;
    while (extra_length - extra_at >= 4) {
      const uint64_t id = readLe(extra + extra_at, 2);
      const uint64_t length = readLe(extra + extra_at + 2, 2);
      if (extra_length - extra_at - 4 < length) fail(where + " ('" + entry.name + "'): bad extra field");
      if (id == kZip64ExtraId) {
        const uint8_t* field = extra + extra_at + 4;
        uint64_t used = 0;
        auto take = [&](uint64_t* value) {
          if (*value != 0xffffffff) return;
          if (length - used < 8) fail(where + " ('" + entry.name + "'): short zip64 extra field");
          *value = readLe(field + used, 8);
          used += 8;
        };
        take(&entry.uncompressed_size);
        take(&entry.compressed_size);
        take(&entry.local_header_offset);
      }
      extra_at += 4 + length;
    }
    if (!index_.emplace(entry.name, entries_.size()).second) {
      fail(where + ": duplicated member name '" + entry.name + "'");
    }
    entries_.push_back(std::move(entry));
    at += record_size;
  }
}

const ZipEntry* ZipReader::find(const std::string& name) const {
  const auto found = index_.find(name);
  return found == index_.end() ? nullptr : &entries_[found->second];
}

const uint8_t* ZipReader::storedData(const ZipEntry& entry) const {
  const std::string where = "zip member '" + entry.name + "'";
  if (entry.flags & 1) fail(where + " is encrypted");
  if (entry.method != 0) {
    fail(where + " is compressed (method " + std::to_string(entry.method) +
         "); only stored members are supported, as written by torch.save()");
  }
  if (entry.compressed_size != entry.uncompressed_size) {
    fail(where + ": stored member with different compressed and uncompressed sizes");
  }
  const uint64_t header = entry.local_header_offset;
  if (header > size_ || size_ - header < kLocalHeaderSize ||
      readLe(data_ + header, 4) != kLocalHeaderSignature) {
    fail(where + ": local header missing or out of bounds");
  }
  const uint64_t start =
      header + kLocalHeaderSize + readLe(data_ + header + 26, 2) + readLe(data_ + header + 28, 2);
  if (start > size_ || size_ - start < entry.compressed_size) {
    fail(where + ": data [" + std::to_string(start) + ", +" +
         std::to_string(entry.compressed_size) + ") runs past the end of the file (" +
         std::to_string(size_) + " bytes); truncated?");
  }
  return data_ + start;
}

void ZipReader::fail(const std::string& what) const { throwInputError(source_, 0, what); }

}  // namespace ffloc
