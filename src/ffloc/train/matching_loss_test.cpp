#include <gtest/gtest.h>

#include <ATen/TensorOperators.h>
#include <ATen/ops/full.h>
#include <ATen/ops/tensor.h>
#include <ATen/ops/zeros.h>

#include <cmath>

#include "ffloc/train/matching_loss.h"

namespace ffloc {
namespace {

TEST(MatchingTargets, NearestTokenWithinTheRadiusElseNoMatch) {
  // Map tokens at x = 0, 1, 2, 3 (the one at 2 has no point); query patches near them.
  at::Tensor map_points = at::zeros({4, 3});
  for (int j = 0; j < 4; ++j) map_points[j][0] = static_cast<float>(j);
  at::Tensor map_valid = at::ones({4}, at::kBool);
  map_valid[2] = false;
  at::Tensor patch_points = at::zeros({5, 3});
  patch_points[0][0] = 0.1f;   // token 0
  patch_points[1][0] = 0.95f;  // token 1
  patch_points[2][0] = 2.0f;   // only token 2 is near, and it has no point: no match
  patch_points[3][0] = 3.05f;  // token 3 but this patch has no ground truth
  patch_points[4][1] = 5.0f;   // far from everything: no match
  at::Tensor patch_valid = at::ones({5}, at::kBool);
  patch_valid[3] = false;
  const at::Tensor radius = at::full({5}, 0.3);
  const at::Tensor targets = matchingTargets(patch_points, patch_valid, map_points, map_valid, radius);
  const std::vector<int64_t> expected = {0, 1, 4, -1, 4};
  for (int i = 0; i < 5; ++i) EXPECT_EQ(targets[i].item<int64_t>(), expected[i]) << i;
}

TEST(MatchingLoss, IsTheCrossEntropyOverLabelledPatches) {
  // Two map tokens and no-match; patch 0 wants token 1, patch 1 no-match, patch 2 is unlabelled.
  const at::Tensor logits = at::tensor(std::vector<float>{0.f, 2.f, 1.f, 1.f, 0.f, 3.f, 9.f, 9.f, 9.f}).reshape({3, 3});
  const at::Tensor targets = at::tensor(std::vector<int64_t>{1, 2, -1});
  const MatchingLossTerm term = matchingLoss(logits, targets);
  const double lse0 = std::log(std::exp(0.0) + std::exp(2.0) + std::exp(1.0));
  const double lse1 = std::log(std::exp(1.0) + std::exp(0.0) + std::exp(3.0));
  EXPECT_NEAR(term.loss.item<double>(), ((lse0 - 2.0) + (lse1 - 3.0)) / 2.0, 1e-6);
  EXPECT_EQ(term.patches, 2);
  EXPECT_DOUBLE_EQ(term.accuracy, 1.0);
  const MatchingLossTerm none = matchingLoss(logits, at::full({3}, -1, at::kLong));
  EXPECT_EQ(none.patches, 0);
  EXPECT_EQ(none.loss.item<double>(), 0.0);
}

TEST(PatchCentreGroundTruth, AveragesTheFourCentrePixels) {
  // One 4x4 patch grid of 2x2 patches of 4 px: centre pixels are 1..2 in each patch.
  at::Tensor points = at::zeros({1, 8, 8, 3});
  at::Tensor valid = at::ones({1, 8, 8}, at::kBool);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) points[0][y][x][0] = static_cast<float>(x), points[0][y][x][1] = static_cast<float>(y);
  valid[0][6][5] = false;  // inside the centre of patch (1, 1)
  valid[0][0][0] = false;  // a corner pixel: does not matter
  const PatchGroundTruth truth = patchCentreGroundTruth(points, valid, 4);
  ASSERT_EQ(truth.points.sizes(), at::IntArrayRef({1, 2, 2, 3}));
  EXPECT_FLOAT_EQ(truth.points[0][0][1][0].item<float>(), 5.5f);  // (4 + 0.5) * ... = pixel 5.5
  EXPECT_FLOAT_EQ(truth.points[0][0][1][1].item<float>(), 1.5f);
  EXPECT_TRUE(truth.valid[0][0][0].item<bool>());
  EXPECT_FALSE(truth.valid[0][1][1].item<bool>());
}

}  // namespace
}  // namespace ffloc
