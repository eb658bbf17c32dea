#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace ffloc {

// FNV-1a, 64 bits: cheap, and enough to detect a corrupted or truncated byte range.
uint64_t fnv1a64(const uint8_t* data, size_t size, uint64_t seed = 0xcbf29ce484222325ULL);
uint64_t fnv1a64(const std::string& text);

// 16 lower-case hexadecimal digits.
std::string hex64(uint64_t value);

}  // namespace ffloc
