#include "ffloc/core/statistics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace ffloc {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// An outside probe found eval's median of an even count to be the lower middle value (4.06 cm
// where numpy gives 4.78 on ten redkitchen queries), the trainer's the upper one and the
// benchmark's the mean: one median now, numpy's.
TEST(Statistics, MedianIsNumpys) {
  EXPECT_DOUBLE_EQ(median({3, 1, 2}), 2);
  EXPECT_DOUBLE_EQ(median({4, 1, 3, 2}), 2.5);
  EXPECT_DOUBLE_EQ(median({0.709, 1.602}), 0.5 * (0.709 + 1.602));
  EXPECT_DOUBLE_EQ(median({7}), 7);
  EXPECT_DOUBLE_EQ(median({}), 0);
  // Failed poses count as infinite errors: with half of them failed the median is infinite.
  EXPECT_DOUBLE_EQ(median({0.01, 0.07, 0.15, kInf}), 0.11);
  EXPECT_TRUE(std::isinf(median({0.01, 0.07, kInf, kInf})));
  EXPECT_TRUE(std::isinf(median({0.01, kInf, kInf})));
}

TEST(Statistics, PercentileIsNearestRank) {
  EXPECT_DOUBLE_EQ(percentile({1, 2, 3, 4, 5, 6, 7, 8, 9, 10}, 0.9), 9);
  EXPECT_DOUBLE_EQ(percentile({10, 1}, 0), 1);
  EXPECT_DOUBLE_EQ(percentile({10, 1}, 1), 10);
  EXPECT_DOUBLE_EQ(percentile({}, 0.5), 0);
}

}  // namespace
}  // namespace ffloc
