#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>

#include "ffloc/core/error.h"
#include "ffloc/retrieval/image_selection.h"
#include "ffloc/retrieval/retrieval_recall.h"

namespace ffloc {
namespace {

// Ten mapping cameras on the x axis (x = 0..9, all looking along +z), each with a one-hot
// descriptor, so a query descriptor's cosine with camera i is its i-th value over its norm and
// every rank below follows by hand.
std::vector<Pose> mappingOnALine() {
  std::vector<Pose> poses(10);
  for (int i = 0; i < 10; ++i) poses[i].t = Eigen::Vector3d(i, 0, 0);
  return poses;
}

std::vector<std::vector<float>> oneHot(size_t count) {
  std::vector<std::vector<float>> out(count, std::vector<float>(count, 0.f));
  for (size_t i = 0; i < count; ++i) out[i][i] = 1.f;
  return out;
}

Pose at(double x) {
  Pose pose;
  pose.t = Eigen::Vector3d(x, 0, 0);
  return pose;
}

template <typename F>
std::string inputErrorOf(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(RetrievalRecall, HandMadeRanksAndRecalls) {
  const std::vector<Pose> mapping = mappingOnALine();
  const std::vector<Pose> queries = {at(3.1), at(6.9), at(0.2), at(5.0)};
  std::vector<std::vector<float>> query_descriptors(4, std::vector<float>(10, 0.f));
  query_descriptors[0][3] = 1.f;  // nearest 3, ranked first
  query_descriptors[1][2] = 0.9f;  // nearest 7, ranked after 2 and 3
  query_descriptors[1][3] = 0.8f;
  query_descriptors[1][7] = 0.5f;
  for (int i = 1; i < 10; ++i) query_descriptors[2][i] = 1.f;  // nearest 0, the only dissimilar one: last
  for (int i = 0; i < 10; ++i) query_descriptors[3][i] = 1.f;  // all tie, so lower index first: 5 is sixth

  RetrievalRecallOptions options;
  options.top_k = {1, 5, 10, 20};
  options.seed = 3;
  const RetrievalRecall result = measureRetrievalRecall(mapping, queries, oneHot(10), query_descriptors, options);

  EXPECT_EQ(result.nearest, (std::vector<size_t>{3, 7, 0, 5}));
  EXPECT_EQ(result.rank, (std::vector<size_t>{1, 3, 10, 6}));
  EXPECT_DOUBLE_EQ(result.median_rank, 4.5);
  ASSERT_EQ(result.recall.size(), 4u);
  EXPECT_EQ(result.recall[0].k, 1u);
  EXPECT_DOUBLE_EQ(result.recall[0].retrieval, 0.25);
  EXPECT_DOUBLE_EQ(result.recall[1].retrieval, 0.5);
  EXPECT_DOUBLE_EQ(result.recall[2].retrieval, 1.0);
  EXPECT_DOUBLE_EQ(result.recall[3].retrieval, 1.0);  // K beyond the map: everything is selected
  // Uniform: K = 1 keeps {0}; K = 5 keeps {0, 2, 4, 6, 8}; only the query nearest camera 0 is covered.
  EXPECT_DOUBLE_EQ(result.recall[0].uniform, 0.25);
  EXPECT_DOUBLE_EQ(result.recall[1].uniform, 0.25);
  EXPECT_DOUBLE_EQ(result.recall[2].uniform, 1.0);
  // Random: one draw per K with the given seed, shared by all queries.
  for (size_t i = 0; i < 2; ++i) {
    const std::vector<size_t> drawn = randomSelection(10, options.top_k[i], options.seed);
    double expected = 0;
    for (size_t nearest : result.nearest) expected += std::count(drawn.begin(), drawn.end(), nearest);
    EXPECT_DOUBLE_EQ(result.recall[i].random, expected / 4) << "K = " << options.top_k[i];
  }
  EXPECT_DOUBLE_EQ(result.recall[2].random, 1.0);
}

TEST(RetrievalRecall, RecallMatchesTopKBySimilarityOnRandomDescriptors) {
  std::mt19937 rng(5);
  std::normal_distribution<float> normal(0.f, 1.f);
  std::uniform_real_distribution<double> position(0.0, 20.0);
  std::vector<Pose> mapping, queries;
  std::vector<std::vector<float>> mapping_descriptors, query_descriptors;
  for (int i = 0; i < 40; ++i) {
    mapping.push_back(at(position(rng)));
    mapping_descriptors.emplace_back(16);
    for (float& v : mapping_descriptors.back()) v = normal(rng);
  }
  for (int i = 0; i < 25; ++i) {
    queries.push_back(at(position(rng)));
    query_descriptors.emplace_back(16);
    for (float& v : query_descriptors.back()) v = normal(rng);
  }
  RetrievalRecallOptions options;
  options.top_k = {1, 3, 8};
  const RetrievalRecall result = measureRetrievalRecall(mapping, queries, mapping_descriptors, query_descriptors, options);
  for (size_t i = 0; i < options.top_k.size(); ++i) {
    double hits = 0;
    for (size_t q = 0; q < queries.size(); ++q) {
      const auto top = topKBySimilarity(mapping_descriptors, query_descriptors[q], options.top_k[i]);
      hits += std::count(top.begin(), top.end(), nearestMappingCamera(mapping, queries[q]));
    }
    EXPECT_DOUBLE_EQ(result.recall[i].retrieval, hits / queries.size()) << "K = " << options.top_k[i];
  }
}

TEST(RetrievalRecall, MappingImagesAsQueriesFindThemselves) {
  // A query that is a mapping image has its own pose (distance 0) and descriptor (cosine 1).
  const std::vector<Pose> mapping = mappingOnALine();
  const auto descriptors = oneHot(10);
  const RetrievalRecall result = measureRetrievalRecall(mapping, mapping, descriptors, descriptors);
  EXPECT_DOUBLE_EQ(result.recall[0].retrieval, 1.0);
  EXPECT_DOUBLE_EQ(result.median_rank, 1.0);
  EXPECT_DOUBLE_EQ(result.recall[0].uniform, 0.1);  // K = 1: only camera 0
}

TEST(RetrievalRecall, BadInputNamesTheField) {
  const std::vector<Pose> mapping = mappingOnALine();
  const auto descriptors = oneHot(10);
  EXPECT_NE(inputErrorOf([&] { measureRetrievalRecall({}, mapping, {}, descriptors); }).find("no mapping images"),
            std::string::npos);
  EXPECT_NE(inputErrorOf([&] { measureRetrievalRecall(mapping, {}, descriptors, {}); }).find("no queries"),
            std::string::npos);
  const std::vector<std::vector<float>> nine(descriptors.begin(), descriptors.begin() + 9);
  EXPECT_NE(inputErrorOf([&] { measureRetrievalRecall(mapping, mapping, nine, descriptors); })
                .find("9 mapping descriptors for 10 mapping poses"),
            std::string::npos);
  EXPECT_NE(inputErrorOf([&] { measureRetrievalRecall(mapping, mapping, descriptors, nine); })
                .find("9 query descriptors for 10 query poses"),
            std::string::npos);
  auto shorter = descriptors;
  shorter[4].resize(3);
  EXPECT_NE(inputErrorOf([&] { measureRetrievalRecall(mapping, mapping, descriptors, shorter); })
                .find("query descriptor 4 has 3 values"),
            std::string::npos);
  RetrievalRecallOptions zero;
  zero.top_k = {5, 0};
  EXPECT_NE(inputErrorOf([&] { measureRetrievalRecall(mapping, mapping, descriptors, descriptors, zero); })
                .find("K must be positive"),
            std::string::npos);
}

}  // namespace
}  // namespace ffloc
