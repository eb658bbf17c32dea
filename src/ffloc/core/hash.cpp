#include "ffloc/core/hash.h"

#include <cstdio>

namespace ffloc {

uint64_t fnv1a64(const uint8_t* data, size_t size, uint64_t hash) {
  for (size_t i = 0; i < size; ++i) {
    hash ^= data[i];
    hash *= 0x100000001b3ULL;
  }
  return hash;
}

uint64_t fnv1a64(const std::string& text) { return fnv1a64(reinterpret_cast<const uint8_t*>(text.data()), text.size()); }

std::string hex64(uint64_t value) {
  char buffer[17];
  std::snprintf(buffer, sizeof(buffer), "%016llx", static_cast<unsigned long long>(value));
  return buffer;
}

}  // namespace ffloc
