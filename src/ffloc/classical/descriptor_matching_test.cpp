#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "ffloc/classical/descriptor_matching.h"

namespace ffloc {
namespace {

using Matches = std::vector<std::pair<int, int>>;

cv::Mat unitRows(int rows, std::mt19937& random) {
  std::normal_distribution<float> normal;
  cv::Mat descriptors(rows, 128, CV_32F);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < 128; ++c) descriptors.at<float>(r, c) = normal(random);
    cv::normalize(descriptors.row(r), descriptors.row(r));
  }
  return descriptors;
}

// The rule matchExactly implements, written the slow and obvious way in double precision: per
// image, the query rows whose nearest target passes the ratio test against the second nearest,
// then for each target only the closest such query row.
std::vector<Matches> referenceMatches(const cv::Mat& query, const std::vector<cv::Mat>& images, float ratio) {
  std::vector<Matches> matches(images.size());
  for (size_t i = 0; i < images.size(); ++i) {
    const cv::Mat& targets = images[i];
    if (targets.rows < 2) continue;
    std::vector<int> best_query(targets.rows, -1);
    std::vector<double> best_distance(targets.rows, 1e300);
    for (int q = 0; q < query.rows; ++q) {
      std::vector<std::pair<double, int>> distances;
      for (int t = 0; t < targets.rows; ++t) distances.emplace_back(cv::norm(query.row(q), targets.row(t), cv::NORM_L2SQR), t);
      std::sort(distances.begin(), distances.end());
      if (!(distances[0].first < double(ratio) * ratio * distances[1].first)) continue;
      const int t = distances[0].second;
      if (distances[0].first < best_distance[t]) {
        best_distance[t] = distances[0].first;
        best_query[t] = q;
      }
    }
    for (int t = 0; t < targets.rows; ++t)
      if (best_query[t] >= 0) matches[i].emplace_back(best_query[t], t);
  }
  return matches;
}

// Image sizes around the scan's 16 lanes (0, 1 and 2 rows; one lane pass and a tail; many
// passes), queries that are noisy copies of targets so that many pass the ratio test, and
// pairs of near-twin targets in the same lane and in different lanes, whose ratio test fails.
TEST(DescriptorMatching, ExactMatchingAgreesWithTheRuleWrittenOut) {
  std::mt19937 random(7);
  const std::vector<int> sizes = {0, 1, 2, 15, 16, 17, 33, 100, 700};
  std::vector<cv::Mat> images;
  for (int size : sizes) images.push_back(unitRows(size, random));
  // Three near twins around one query row, as far from it as from each other: targets 3 and 19
  // share a lane of the scan, 40 is in another. That row's ratio test must fail. And two targets
  // exactly alike in different lanes (5 and 22): a row nearest to them matches neither.
  cv::Mat& large = images.back();
  const cv::Mat ambiguous = unitRows(1, random);
  for (int t : {3, 19, 40}) cv::normalize(ambiguous + 0.05f * unitRows(1, random), large.row(t));
  large.row(5).copyTo(large.row(22));
  std::normal_distribution<float> normal;
  std::uniform_int_distribution<size_t> image_of(0, images.size() - 1);
  cv::Mat query = unitRows(300, random);
  for (int q = 0; q < 200; ++q) {
    const cv::Mat& source = images[image_of(random)];
    if (source.rows == 0) continue;
    const int t = static_cast<int>(random() % source.rows);
    cv::Mat noisy = source.row(t).clone();
    for (int c = 0; c < 128; ++c) noisy.at<float>(0, c) += 0.05f * normal(random);
    cv::normalize(noisy, query.row(q));
  }
  ambiguous.copyTo(query.row(200));
  cv::normalize(large.row(5) + 0.01f * unitRows(1, random), query.row(201));

  std::vector<const cv::Mat*> pointers;
  for (const cv::Mat& image : images) pointers.push_back(&image);
  const std::vector<Matches> exact = matchExactly(query, pointers, 0.8f);
  const std::vector<Matches> expected = referenceMatches(query, images, 0.8f);
  ASSERT_EQ(exact.size(), images.size());
  size_t total = 0;
  for (size_t i = 0; i < images.size(); ++i) {
    const std::set<std::pair<int, int>> found(exact[i].begin(), exact[i].end());
    const std::set<std::pair<int, int>> wanted(expected[i].begin(), expected[i].end());
    EXPECT_EQ(found, wanted) << "image " << i << " of " << images[i].rows << " rows";
    total += exact[i].size();
  }
  EXPECT_GT(total, 100u);  // the noisy copies matched: the comparison is not of empty sets
  for (const auto& [q, t] : exact.back()) {
    EXPECT_NE(q, 200) << "matched target " << t << " despite its twins";
    EXPECT_NE(q, 201) << "matched target " << t << " though 5 and 22 are alike";
  }
}

}  // namespace
}  // namespace ffloc
