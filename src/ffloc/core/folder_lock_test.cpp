#include "ffloc/core/folder_lock.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"

namespace ffloc {
namespace {

// A second holder waits (and is told so) until the first lets go.
TEST(FolderLock, ASecondHolderWaitsForTheFirst) {
  const auto folder = testing::makeTempDir("ffloc-folder-lock");
  std::atomic<bool> waited{false}, second_holds{false};
  auto first = std::make_unique<FolderLock>(folder, [] { FAIL() << "the folder was free"; });
  std::thread second([&] {
    const FolderLock lock(folder, [&] { waited = true; });
    second_holds = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_FALSE(second_holds);
  first.reset();
  second.join();
  EXPECT_TRUE(waited);
  EXPECT_TRUE(second_holds);
}

TEST(FolderLock, AMissingFolderIsNamed) {
  try {
    FolderLock lock("/nonexistent/ffloc-folder", nullptr);
    FAIL() << "locked a folder that does not exist";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/ffloc-folder"), std::string::npos);
  }
}

}  // namespace
}  // namespace ffloc
