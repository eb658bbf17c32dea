#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "ffloc/classical/descriptor_matching.h"
#include "ffloc/classical/sift_features.h"
#include "ffloc/core/error.h"

namespace ffloc {
namespace {

using Matches = std::vector<std::pair<int, int>>;

// Non-negative unit rows, as RootSIFT's. Every fifth row has a few dominant dimensions, so that
// bytes above 127 occur, where unsigned and signed bytes differ.
cv::Mat unitRows(int rows, std::mt19937& random) {
  std::normal_distribution<float> normal;
  cv::Mat descriptors(rows, 128, CV_32F);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < 128; ++c) descriptors.at<float>(r, c) = std::abs(normal(random));
    if (r % 5 == 0)
      for (int c = 0; c < 3; ++c) descriptors.at<float>(r, static_cast<int>(random() % 128)) += 20.0f;
    cv::normalize(descriptors.row(r), descriptors.row(r));
  }
  return descriptors;
}

cv::Mat noisyUnitRow(const cv::Mat& row, float sigma, std::mt19937& random) {
  std::normal_distribution<float> normal;
  cv::Mat noisy = row.clone();
  for (int c = 0; c < 128; ++c) noisy.at<float>(0, c) = std::abs(noisy.at<float>(0, c) + sigma * normal(random));
  cv::normalize(noisy, noisy);
  return noisy;
}

// The rule matchExactly implements, written the slow and obvious way in integers: per
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
      for (int t = 0; t < targets.rows; ++t) {
        int64_t squared = 0;
        for (int c = 0; c < 128; ++c) {
          const int64_t difference = int64_t{query.at<uint8_t>(q, c)} - targets.at<uint8_t>(t, c);
          squared += difference * difference;
        }
        distances.emplace_back(static_cast<double>(squared), t);
      }
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
// passes), 300 query rows (the VNNI kernel's groups of 8 and a tail of 4), queries that are noisy
// copies of targets so that many pass the ratio test, and pairs of near-twin targets in the same
// lane and in different lanes, whose ratio test fails. The kernel must give exactly the rule's
// matches.
void expectTheRulesMatches(ProductKernel kernel) {
  std::mt19937 random(7);
  const std::vector<int> sizes = {0, 1, 2, 15, 16, 17, 33, 100, 700};
  std::vector<cv::Mat> unit_images;
  for (int size : sizes) unit_images.push_back(unitRows(size, random));
  // Three near twins around one query row, as far from it as from each other: targets 3 and 19
  // share a lane of the scan, 40 is in another. That row's ratio test must fail. And two targets
  // exactly alike in different lanes (5 and 22): a row nearest to them matches neither.
  cv::Mat& large = unit_images.back();
  const cv::Mat ambiguous = unitRows(1, random);
  for (int t : {3, 19, 40}) noisyUnitRow(ambiguous, 0.02f, random).copyTo(large.row(t));
  large.row(5).copyTo(large.row(22));
  std::uniform_int_distribution<size_t> image_of(0, unit_images.size() - 1);
  cv::Mat unit_query = unitRows(300, random);
  for (int q = 0; q < 200; ++q) {
    const cv::Mat& source = unit_images[image_of(random)];
    if (source.rows == 0) continue;
    noisyUnitRow(source.row(static_cast<int>(random() % source.rows)), 0.01f, random).copyTo(unit_query.row(q));
  }
  ambiguous.copyTo(unit_query.row(200));
  noisyUnitRow(large.row(5), 0.005f, random).copyTo(unit_query.row(201));

  std::vector<cv::Mat> images;
  for (const cv::Mat& image : unit_images) images.push_back(image.empty() ? cv::Mat(0, 128, CV_8U) : quantizeDescriptors(image));
  const cv::Mat query = quantizeDescriptors(unit_query);
  std::vector<const cv::Mat*> pointers;
  for (const cv::Mat& image : images) pointers.push_back(&image);
  const std::vector<Matches> expected = referenceMatches(query, images, 0.8f);
  const std::vector<Matches> exact = matchExactly(query, pointers, 0.8f, kernel);
  ASSERT_EQ(exact.size(), images.size());
  size_t total = 0;
  for (size_t i = 0; i < images.size(); ++i) {
    const std::set<std::pair<int, int>> found(exact[i].begin(), exact[i].end());
    const std::set<std::pair<int, int>> wanted(expected[i].begin(), expected[i].end());
    EXPECT_EQ(found, wanted) << "image " << i << " of " << images[i].rows << " rows";
    total += exact[i].size();
  }
  EXPECT_GT(total, 80u);  // the noisy copies matched (99; collisions in the small images cost the rest)
  for (const auto& [q, t] : exact.back()) {
    EXPECT_NE(q, 200) << "matched target " << t << " despite its twins";
    EXPECT_NE(q, 201) << "matched target " << t << " though 5 and 22 are alike";
  }
}

// One query at the ratio test's edge (0.8: a match needs d1 < 0.64 d2): against {A, B} its
// squared distances are 6399 and 10000 and it matches A, against {A', B} 6401 and 10000 and it
// does not. Its bytes are 150 and the targets' above 127, their sums unequal, so a distance off
// by any amount (an offset wrong, a byte read as signed) turns one of the two decisions. Both
// images alone (2 targets, under one block of 16), together, and with 28 more (32 in all: whole
// blocks, no padding).
void expectTheEdgeDecided(ProductKernel kernel) {
  cv::Mat query(1, 128, CV_8U, cv::Scalar(0));
  for (int c = 0; c < 5; ++c) query.at<uint8_t>(0, c) = 150;
  const auto near_query = [&](const std::vector<int>& steps) {
    cv::Mat target = query.clone();
    for (size_t c = 0; c < steps.size(); ++c) target.at<uint8_t>(0, static_cast<int>(c)) += steps[c];
    return target;
  };
  cv::Mat matched, unmatched;
  cv::vconcat(near_query({79, 12, 3, 2, 1}), near_query({100}), matched);
  cv::vconcat(near_query({80, 1}), near_query({100}), unmatched);
  const cv::Mat far(28, 128, CV_8U, cv::Scalar(0));
  const std::vector<std::vector<const cv::Mat*>> calls = {{&matched}, {&unmatched}, {&matched, &unmatched},
                                                          {&matched, &unmatched, &far}};
  for (const std::vector<const cv::Mat*>& images : calls) {
    SCOPED_TRACE(std::to_string(images.size()) + " images");
    std::vector<std::vector<float>> ratios;
    const std::vector<Matches> found = matchExactly(query, images, 0.8f, kernel, &ratios);
    ASSERT_EQ(found.size(), images.size());
    ASSERT_EQ(ratios.size(), images.size());
    for (size_t i = 0; i < images.size(); ++i) {
      const Matches wanted = images[i] == &matched ? Matches{{0, 0}} : Matches{};
      EXPECT_EQ(found[i], wanted) << "image " << i;
      ASSERT_EQ(ratios[i].size(), found[i].size());
      if (!ratios[i].empty()) EXPECT_FLOAT_EQ(ratios[i][0], std::sqrt(6399.0f / 10000.0f));
    }
    // A looser test lets the other image's query through, and says by how much it failed 0.8.
    const std::vector<Matches> loose = matchExactly(query, images, 0.9f, kernel, &ratios);
    for (size_t i = 0; i < images.size(); ++i) {
      if (images[i] == &far) continue;
      ASSERT_EQ(loose[i], (Matches{{0, 0}})) << "image " << i;
      EXPECT_FLOAT_EQ(ratios[i][0], std::sqrt((images[i] == &matched ? 6399.0f : 6401.0f) / 10000.0f));
    }
  }
}

TEST(DescriptorMatching, BlasProductsGiveTheRulesMatches) {
  expectTheRulesMatches(ProductKernel::kBlas);
  expectTheEdgeDecided(ProductKernel::kBlas);
}

TEST(DescriptorMatching, VnniProductsGiveTheRulesMatches) {
  if (!hasVnniProducts()) GTEST_SKIP() << "this CPU has no AVX-512 VNNI (the BLAS test covers its matching)";
  expectTheRulesMatches(ProductKernel::kFastest);
  expectTheEdgeDecided(ProductKernel::kFastest);
}

TEST(DescriptorMatching, RefusesUnquantizedDescriptors) {
  std::mt19937 random(3);
  const cv::Mat unit = unitRows(4, random), quantized = quantizeDescriptors(unit);
  const std::vector<const cv::Mat*> floats = {&unit}, bytes = {&quantized};
  EXPECT_THROW(matchExactly(quantized, floats, 0.8f), InputError);
  EXPECT_THROW(matchExactly(unit, bytes, 0.8f), InputError);
  EXPECT_NO_THROW(matchExactly(quantized, bytes, 0.8f));
}

}  // namespace
}  // namespace ffloc
