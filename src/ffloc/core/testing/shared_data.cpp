#include "ffloc/core/testing/shared_data.h"

#include <cstdlib>
#include <mutex>
#include <unistd.h>
#include <vector>

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

namespace {

// The folders this process made, removed when it exits: a full `make test` used to leave about
// 250 folders and 600 MB in /tmp. A forked child (ChildProcess, death tests) inherits the list but
// must not remove its parent's folders, hence the owner's pid. FFLOC_KEEP_TEST_DIRS keeps them
// for a look after a failure.
class TempDirs {
 public:
  std::filesystem::path make(const std::string& prefix) {
    const std::lock_guard<std::mutex> lock(mutex_);
    const auto dir = std::filesystem::temp_directory_path() /
                     (prefix + "-" + std::to_string(getpid()) + "-" + std::to_string(dirs_.size()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    dirs_.push_back(dir);
    return dir;
  }

  ~TempDirs() {
    const char* keep = std::getenv("FFLOC_KEEP_TEST_DIRS");
    if (getpid() != owner_ || (keep && *keep)) return;
    for (const auto& dir : dirs_) {
      std::error_code ignored;  // a folder a test removed itself, or one still in use, is no failure
      std::filesystem::remove_all(dir, ignored);
    }
  }

 private:
  const pid_t owner_ = getpid();
  std::mutex mutex_;
  std::vector<std::filesystem::path> dirs_;
};

}  // namespace

std::filesystem::path makeTempDir(const std::string& prefix) {
  static TempDirs dirs;
  return dirs.make(prefix);
}

}  // namespace ffloc::testing
