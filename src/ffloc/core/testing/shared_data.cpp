#include "ffloc/core/testing/shared_data.h"

#include <atomic>
#include <cstdlib>
#include <random>
#include <unistd.h>

namespace ffloc::testing {

std::optional<std::filesystem::path> sharedDir() {
  const char* env = std::getenv("FFLOC_SHARED_DIR");
  if (!env || !*env) return std::nullopt;
  std::filesystem::path dir(env);
  if (!std::filesystem::is_directory(dir)) return std::nullopt;
  return dir;
}

std::optional<std::filesystem::path> sharedPath(const std::string& relative) {
  const auto dir = sharedDir();
  if (!dir) return std::nullopt;
  const auto path = *dir / relative;
  if (!std::filesystem::exists(path)) return std::nullopt;
  return path;
}

std::filesystem::path makeTempDir(const std::string& prefix) {
  static std::atomic<int> counter{0};
  const auto dir = std::filesystem::temp_directory_path() /
                   (prefix + "-" + std::to_string(getpid()) + "-" + std::to_string(counter++));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace ffloc::testing
