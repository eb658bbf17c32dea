#include "ffloc/core/number_text.h"

#include <charconv>

namespace ffloc {

std::string formatNumber(double value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

}  // namespace ffloc
