#include "ffloc/core/error.h"

namespace ffloc {

std::string locate(const std::string& file, int line, const std::string& what) {
  if (line > 0) return file + ":" + std::to_string(line) + ": " + what;
  return file + ": " + what;
}

void throwInputError(const std::string& file, int line, const std::string& what) {
  throw InputError(locate(file, line, what));
}

}  // namespace ffloc
