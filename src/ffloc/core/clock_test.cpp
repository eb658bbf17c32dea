#include "ffloc/core/clock.h"

#include <gtest/gtest.h>

namespace ffloc {
namespace {

TEST(Clock, UtcTimestampIsIso8601ToTheMillisecond) {
  using std::chrono::milliseconds;
  const std::chrono::system_clock::time_point epoch{};
  EXPECT_EQ(utcTimestamp(epoch), "1970-01-01T00:00:00.000Z");
  // 5 Dec 2026 09:20:01.123 UTC.
  EXPECT_EQ(utcTimestamp(epoch + milliseconds(1796462401123LL)), "2026-12-05T09:20:01.123Z");
  EXPECT_EQ(utcTimestamp(epoch - milliseconds(1)), "1969-12-31T23:59:59.999Z");
}

}  // namespace
}  // namespace ffloc
