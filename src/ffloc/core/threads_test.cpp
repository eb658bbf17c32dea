#include "ffloc/core/threads.h"

#include <gtest/gtest.h>

#include <opencv2/core/utility.hpp>
#include <thread>

#include "ffloc/core/error.h"

namespace ffloc {
namespace {

// Every library entry point (the Python bindings among them) goes through resolveThreadCount: a
// count past kMaxThreads crashed OpenCV's pool (beyond 65536) or crawled, a negative one meant
// nothing.
TEST(Threads, CountsOutsideTheRangeAreRefusedNamingTheField) {
  EXPECT_EQ(resolveThreadCount(3), 3);
  EXPECT_EQ(resolveThreadCount(kMaxThreads), kMaxThreads);
  EXPECT_EQ(resolveThreadCount(0), static_cast<int>(std::max(1u, std::thread::hardware_concurrency())));
  for (const int bad : {-1, kMaxThreads + 1, 65537}) {
    try {
      resolveThreadCount(bad);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("threads: must be 0 (all hardware threads) to 256", 0), 0u) << e.what();
    }
  }
}

// More threads than cores: the count is kept for the pools that take it, OpenCV's runs one a core
// (TBB would not start the rest, and said so on stderr).
TEST(Threads, OpenCvRunsAtMostOneThreadPerCore) {
  const int cores = cv::getNumberOfCPUs();  // the cores this process may run on
  EXPECT_EQ(setLibraryThreadCount(cores + 3), cores + 3);
  EXPECT_EQ(cv::getNumThreads(), cores);
  EXPECT_EQ(setLibraryThreadCount(1), 1);
  EXPECT_EQ(cv::getNumThreads(), 1);
  setLibraryThreadCount(0);
}

}  // namespace
}  // namespace ffloc
