#include "ffloc/io/input_file.h"

#include <algorithm>

#include "ffloc/core/error.h"

namespace ffloc {

void requireRegularFile(const std::filesystem::path& path, const std::string& what) {
  std::error_code error;
  const std::filesystem::file_status status = std::filesystem::status(path, error);
  if (status.type() == std::filesystem::file_type::not_found) throwInputError(path.string(), 0, what + " not found");
  if (error) throwInputError(path.string(), 0, what + ": " + error.message());
  if (status.type() == std::filesystem::file_type::directory)
    throwInputError(path.string(), 0, what + " expected, found a folder");
  if (status.type() != std::filesystem::file_type::regular)
    throwInputError(path.string(), 0, what + " expected, found something that is not a regular file (FIFO, device or socket)");
}

bool liesWithin(const std::filesystem::path& path, const std::filesystem::path& folder) {
  std::error_code ignored;
  const std::filesystem::path inner = std::filesystem::weakly_canonical(std::filesystem::absolute(path), ignored);
  std::filesystem::path outer = std::filesystem::weakly_canonical(std::filesystem::absolute(folder), ignored);
  if (!outer.has_filename()) outer = outer.parent_path();  // "d/" ends in an empty part
  if (outer.empty()) return false;
  return std::mismatch(outer.begin(), outer.end(), inner.begin(), inner.end()).first == outer.end();
}

}  // namespace ffloc
