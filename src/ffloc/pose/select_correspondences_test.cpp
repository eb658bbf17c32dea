#include "ffloc/pose/select_correspondences.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <set>

namespace ffloc {
namespace {

Correspondences withConfidences(const std::vector<float>& confidences) {
  Correspondences c;
  for (size_t i = 0; i < confidences.size(); ++i)
    c.add(Eigen::Vector2d(i, 0), Eigen::Vector3d(0, 0, static_cast<double>(i)), confidences[i]);
  return c;
}

TEST(SelectCorrespondences, KeepsConfidenceAtOrAboveTheThresholdAndFiniteValues) {
  const float inf = std::numeric_limits<float>::infinity();
  Correspondences c = withConfidences({1.0f, 1.5f, 1.49f, 2.0f, inf, std::nanf(""), 3.0f});
  c.points[6].x() = std::numeric_limits<double>::quiet_NaN();
  Rng rng(0);
  EXPECT_EQ(selectCorrespondences(c, 1.5f, 5000, &rng), (std::vector<int>{1, 3, 4}));
}

TEST(SelectCorrespondences, SubsamplesToADistinctSortedSubsetThatDependsOnTheSeed) {
  std::vector<float> confidences(10000, 2.0f);
  for (size_t i = 0; i < confidences.size(); i += 2) confidences[i] = 1.0f;  // half filtered out
  const Correspondences c = withConfidences(confidences);
  Rng rng(5), same(5), other(6);
  const std::vector<int> a = selectCorrespondences(c, 1.5f, 1000, &rng);
  ASSERT_EQ(a.size(), 1000u);
  EXPECT_TRUE(std::is_sorted(a.begin(), a.end()));
  EXPECT_EQ(std::set<int>(a.begin(), a.end()).size(), 1000u);
  for (int i : a) EXPECT_EQ(i % 2, 1);
  // Spread over the whole range, not a prefix.
  EXPECT_LT(a.front(), 200);
  EXPECT_GT(a.back(), 9800);
  EXPECT_EQ(selectCorrespondences(c, 1.5f, 1000, &same), a);
  EXPECT_NE(selectCorrespondences(c, 1.5f, 1000, &other), a);
}

TEST(SelectCorrespondences, FallsBackToTheMostConfidentWhenTooFewPassTheThreshold) {
  Correspondences c = withConfidences({1.2f, 1.4f, 1.1f, 1.6f, 1.3f, 1.4f, std::nanf(""), 1.0f});
  Rng rng(0);
  // Only index 3 passes 1.5; with min_count 4 the four most confident finite pairs are used,
  // the tie at 1.4 broken by index and NaN never taken.
  EXPECT_EQ(selectCorrespondences(c, 1.5f, 5000, &rng, 4), (std::vector<int>{1, 3, 4, 5}));
  EXPECT_EQ(selectCorrespondences(c, 1.5f, 5000, &rng, 1), (std::vector<int>{3}));
  EXPECT_EQ(selectCorrespondences(c, 1.5f, 5000, &rng, 100), (std::vector<int>{0, 1, 2, 3, 4, 5, 7}));
  EXPECT_EQ(selectCorrespondences(c, 1.5f, 2, &rng, 4).size(), 2u);
}

}  // namespace
}  // namespace ffloc
