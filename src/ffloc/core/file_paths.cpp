#include "ffloc/core/file_paths.h"

#include <cstdlib>
#include <string>

#include "ffloc/core/error.h"

namespace ffloc {

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

std::optional<int> openDescriptorNamed(const std::filesystem::path& path) {
  const std::string text = path.lexically_normal().string();
  if (text == "/dev/stdout") return 1;
  if (text == "/dev/stderr") return 2;
  for (const std::string prefix : {"/dev/fd/", "/proc/self/fd/"}) {
    if (text.rfind(prefix, 0) != 0 || text.size() == prefix.size()) continue;
    const std::string number = text.substr(prefix.size());
    if (number.find_first_not_of("0123456789") != std::string::npos || number.size() > 9) return std::nullopt;
    return std::atoi(number.c_str());
  }
  return std::nullopt;
}

}  // namespace ffloc
