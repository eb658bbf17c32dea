#include "ffloc/core/progress.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <thread>

namespace ffloc {
namespace {

size_t lines(const std::string& text) { return static_cast<size_t>(std::count(text.begin(), text.end(), '\n')); }

// Under ctest stderr is a pipe, as for a run logged to a file: a line each interval while the
// work goes on (before, nothing until a stage ended), and one at the end.
TEST(ProgressBar, ALogGetsALineEachIntervalAndOneAtTheEnd) {
  ::testing::internal::CaptureStderr();
  ProgressBar bar("mapping", 10, false, std::chrono::milliseconds(30));
  for (size_t done = 1; done <= 10; ++done) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    bar.update(done);
  }
  bar.finish();
  const std::string log = ::testing::internal::GetCapturedStderr();
  EXPECT_GE(lines(log), 3u) << log;
  EXPECT_LE(lines(log), 8u) << log;
  EXPECT_EQ(log.find('\r'), std::string::npos) << log;
  EXPECT_NE(log.find("mapping [==============================] 10/10"), std::string::npos) << log;
  EXPECT_NE(log.find("eta"), std::string::npos) << log;
}

TEST(ProgressBar, WorkStoppedEarlyEndsItsBarWhereItStopped) {
  ::testing::internal::CaptureStderr();
  ProgressBar bar("validating", 100000, false, std::chrono::hours(1));
  bar.update(208);
  bar.finish(208);
  const std::string log = ::testing::internal::GetCapturedStderr();
  EXPECT_NE(log.find("validating [                              ] 208/100000"), std::string::npos) << log;
  EXPECT_EQ(log.find("100000/100000"), std::string::npos) << log;
}

TEST(ProgressBar, QuietPrintsNothing) {
  ::testing::internal::CaptureStderr();
  ProgressBar bar("mapping", 3, true, std::chrono::milliseconds(0));
  for (size_t done = 1; done <= 3; ++done) bar.update(done);
  bar.finish();
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
}

}  // namespace
}  // namespace ffloc
