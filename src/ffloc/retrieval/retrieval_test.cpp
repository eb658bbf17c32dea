#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "ffloc/core/error.h"
#include "ffloc/retrieval/global_descriptor.h"
#include "ffloc/retrieval/image_selection.h"

namespace ffloc {
namespace {

std::vector<float> randomTokens(std::mt19937& rng, int count, int dim) {
  std::normal_distribution<float> n(0.f, 1.f);
  std::vector<float> t(static_cast<size_t>(count) * dim);
  for (float& v : t) v = n(rng);
  return t;
}

TEST(GlobalDescriptor, UnitNormAndPoolingOrderInvariant) {
  std::mt19937 rng(1);
  const int count = 50, dim = 16;
  std::vector<float> tokens = randomTokens(rng, count, dim);
  const auto d = globalDescriptor(tokens.data(), count, dim);
  ASSERT_EQ(d.size(), 2u * dim);
  double norm = 0;
  for (float v : d) norm += v * v;
  EXPECT_NEAR(norm, 1.0, 1e-6);
  // Shuffling the tokens does not change a pooled descriptor.
  std::vector<float> reversed(tokens.size());
  for (int t = 0; t < count; ++t)
    std::copy(tokens.begin() + t * dim, tokens.begin() + (t + 1) * dim, reversed.begin() + (count - 1 - t) * dim);
  EXPECT_NEAR(cosineSimilarity(d, globalDescriptor(reversed.data(), count, dim)), 1.0f, 1e-6);
}

TEST(GlobalDescriptor, GemIsThePowerMeanOfEachSign) {
  // One channel with values {1, 2, -3}: positive part ((1^3 + 2^3) / 3)^(1/3), negative (27 / 3)^(1/3).
  const std::vector<float> tokens = {1.f, 2.f, -3.f};
  GlobalDescriptorOptions options;
  options.p = 3.0;
  const auto d = globalDescriptor(tokens.data(), 3, 1, options);
  const double pos = std::cbrt(9.0 / 3.0), neg = std::cbrt(27.0 / 3.0);
  const double norm = std::sqrt(pos * pos + neg * neg);
  EXPECT_NEAR(d[0], pos / norm, 1e-6);
  EXPECT_NEAR(d[1], neg / norm, 1e-6);
}

TEST(Selection, TopKFindsTheMostSimilar) {
  std::mt19937 rng(2);
  std::vector<std::vector<float>> database;
  for (int i = 0; i < 20; ++i) {
    auto tokens = randomTokens(rng, 30, 8);
    database.push_back(globalDescriptor(tokens.data(), 30, 8));
  }
  // A query that is a slightly perturbed copy of entry 7 ranks it first.
  std::vector<float> query = database[7];
  query[0] += 0.01f;
  const auto top = topKBySimilarity(database, query, 5);
  ASSERT_EQ(top.size(), 5u);
  EXPECT_EQ(top[0], 7u);
  for (size_t i = 1; i < top.size(); ++i)
    EXPECT_GE(cosineSimilarity(database[top[i - 1]], query), cosineSimilarity(database[top[i]], query));
  EXPECT_EQ(topKBySimilarity(database, query, 100).size(), 20u);
  EXPECT_THROW(cosineSimilarity({1.f}, {1.f, 2.f}), std::invalid_argument);
}

TEST(Selection, UniformAndRandom) {
  EXPECT_EQ(uniformSelection(10, 5), (std::vector<size_t>{0, 2, 4, 6, 8}));
  EXPECT_EQ(uniformSelection(3, 5), (std::vector<size_t>{0, 1, 2}));
  EXPECT_TRUE(uniformSelection(0, 5).empty());
  const auto a = randomSelection(100, 10, 42), b = randomSelection(100, 10, 42), c = randomSelection(100, 10, 43);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
  ASSERT_EQ(a.size(), 10u);
  for (size_t i = 1; i < a.size(); ++i) EXPECT_LT(a[i - 1], a[i]);
  EXPECT_LT(a.back(), 100u);
  EXPECT_EQ(parseImageSelection("uniform"), ImageSelection::kUniform);
  EXPECT_THROW(parseImageSelection("best"), InputError);
}

TEST(Selection, NearestMappingCameraPrefersSimilarViewpoints) {
  Pose q;
  std::vector<Pose> mapping(3);
  mapping[0].t = Eigen::Vector3d(0.1, 0, 0);
  mapping[0].R = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix();  // close but facing away
  mapping[1].t = Eigen::Vector3d(0.5, 0, 0);
  mapping[2].t = Eigen::Vector3d(1.0, 0, 0);
  EXPECT_EQ(nearestMappingCamera(mapping, q), 1u);
}

}  // namespace
}  // namespace ffloc
