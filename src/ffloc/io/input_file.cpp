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

std::filesystem::path followSymlinks(const std::filesystem::path& path) {
  std::filesystem::path target = path;
  std::error_code error;
  for (int hops = 0; std::filesystem::is_symlink(target, error); ++hops) {
    if (hops == 40) throwInputError(path.string(), 0, "a loop of symbolic links");
    const std::filesystem::path link = std::filesystem::read_symlink(target, error);
    if (error) throwInputError(target.string(), 0, "cannot read the symbolic link: " + error.message());
    target = link.is_absolute() ? link : target.parent_path() / link;
  }
  return target;
}

}  // namespace ffloc
