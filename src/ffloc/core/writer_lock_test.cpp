#include "ffloc/core/writer_lock.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <thread>

#include "ffloc/core/error.h"
#include "ffloc/core/progress.h"
#include "ffloc/core/testing/shared_data.h"

namespace ffloc {
namespace {

// A second writer of the same file waits (and is told so) until the first lets go; a writer of
// another file in the same folder does not.
TEST(WriterLock, ASecondWriterOfTheFileWaitsForTheFirst) {
  const auto folder = testing::makeTempDir("ffloc-writer-lock");
  std::atomic<bool> waited{false}, second_holds{false};
  auto first = std::make_unique<WriterLock>(folder / "m.ffmap", [] { FAIL() << "the file was free"; });
  { const WriterLock other(folder / "n.ffmap", [] { FAIL() << "another file's writer waited"; }); }
  std::thread second([&] {
    const WriterLock lock(folder / "m.ffmap", [&] { waited = true; });
    second_holds = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_FALSE(second_holds);
  first.reset();
  second.join();
  EXPECT_TRUE(waited);
  EXPECT_TRUE(second_holds);
}

// The wait blocked in flock, deaf to Python's Ctrl-C, which the library hears only by asking
// (StopCheck): asked while waiting, it ends the wait.
TEST(WriterLock, AWaitEndsWhenAStopIsAsked) {
  const auto folder = testing::makeTempDir("ffloc-writer-lock");
  const WriterLock first(folder / "m.ffmap", nullptr);
  int asked = 0;
  const StopCheck stop([&] { return ++asked >= 3; });
  bool waited = false;
  try {
    const WriterLock second(folder / "m.ffmap", [&] { waited = true; });
    ADD_FAILURE() << "locked a file another writer holds";
  } catch (const Stopped& e) {
    EXPECT_NE(std::string(e.what()).find(".m.ffmap.lock: stopped"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(waited);
  EXPECT_EQ(asked, 3);
  const WriterLock other(folder / "n.ffmap", nullptr);  // the stop asked nothing of a free file
  EXPECT_EQ(asked, 3);
}

// The error named the hidden lock file, which the user never gave, rather than the map.
TEST(WriterLock, AFolderThatDoesNotExistIsNamedWithTheFileToWrite) {
  try {
    WriterLock lock("/nonexistent/ffloc-folder/m.ffmap", nullptr);
    FAIL() << "locked in a folder that does not exist";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "/nonexistent/ffloc-folder/m.ffmap: output folder does not exist");
  }
  try {
    WriterLock lock("/proc/m.ffmap", nullptr);  // a folder where no one, root included, makes files
    FAIL() << "locked in /proc";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/proc/m.ffmap: cannot make files in its folder: "), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace ffloc
