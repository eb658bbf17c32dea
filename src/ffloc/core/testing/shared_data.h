#pragma once

#include <filesystem>
#include <optional>
#include <string>

namespace ffloc::testing {

// The read-only shared folder (datasets, fixtures) beside the checkout, from FFLOC_SHARED_DIR
// or the path CMake recorded. Empty when it is not there, so tests can skip.
std::optional<std::filesystem::path> sharedDir();

// sharedDir()/relative when it exists.
std::optional<std::filesystem::path> sharedPath(const std::string& relative);

// A fresh empty temporary directory, unique per call, removed when the process exits
// (kept when FFLOC_KEEP_TEST_DIRS is set).
std::filesystem::path makeTempDir(const std::string& prefix);

}  // namespace ffloc::testing

// Skips the current test, saying why, when the shared path is missing.
#define FFLOC_REQUIRE_SHARED(var, relative)                                                  \
  const auto var##_opt = ::ffloc::testing::sharedPath(relative);                             \
  if (!var##_opt) GTEST_SKIP() << "shared data '" << (relative) << "' not found (../shared " \
                                  "is absent on this machine)";                               \
  const std::filesystem::path var = *var##_opt
