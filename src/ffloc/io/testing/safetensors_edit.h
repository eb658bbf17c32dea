#pragma once

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>

#include <nlohmann/json.hpp>

// Edits of safetensors files in place, for the tests of their readers: damage that leaves a valid
// safetensors file, which only a checksum can tell, and files as written before checksums.
namespace ffloc::testing {

struct SafetensorsBytes {
  std::string bytes;
  uint64_t header_size = 0;
  nlohmann::json header;
};

inline SafetensorsBytes readSafetensorsBytes(const std::filesystem::path& file) {
  SafetensorsBytes out;
  std::ifstream in(file, std::ios::binary);
  out.bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  std::memcpy(&out.header_size, out.bytes.data(), sizeof(out.header_size));  // little-endian
  out.header = nlohmann::json::parse(out.bytes.substr(8, out.header_size));
  return out;
}

inline void writeBytes(const std::filesystem::path& file, const std::string& bytes) {
  std::ofstream(file, std::ios::binary | std::ios::trunc) << bytes;
}

// Flips the lowest bit of byte `at` of tensor `name`'s data.
inline void flipTensorByte(const std::filesystem::path& file, const std::string& name, size_t at = 0) {
  SafetensorsBytes parts = readSafetensorsBytes(file);
  const size_t begin = parts.header.at(name).at("data_offsets")[0].get<size_t>();
  parts.bytes[8 + parts.header_size + begin + at] ^= 0x01;
  writeBytes(file, parts.bytes);
}

// Rewrites the header with its __metadata__ passed through `edit`; the tensors' bytes stay.
inline void editMetadata(const std::filesystem::path& file, const std::function<void(nlohmann::json&)>& edit) {
  SafetensorsBytes parts = readSafetensorsBytes(file);
  edit(parts.header["__metadata__"]);
  std::string header = parts.header.dump();
  header.append((8 - header.size() % 8) % 8, ' ');
  const uint64_t size = header.size();
  std::string length(sizeof(size), '\0');
  std::memcpy(length.data(), &size, sizeof(size));
  writeBytes(file, length + header + parts.bytes.substr(8 + parts.header_size));
}

}  // namespace ffloc::testing
