#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

namespace ffloc {

// The matching head's training signal (docs/training.md, "The matching family"): which map token
// each query patch should pick, from the correspondences known in training, and the
// cross-entropy of its logits against that choice, with a no-match class.

// Ground truth at the patch centres of a query, from per-pixel ground truth: the mean of the four
// pixels around each centre ((c + 0.5) p - 0.5 lies between pixels cp + p/2 - 1 and cp + p/2),
// valid where all four are.
struct PatchGroundTruth {
  at::Tensor points;  // (B, rows, cols, 3)
  at::Tensor valid;   // (B, rows, cols) bool
};
PatchGroundTruth patchCentreGroundTruth(const at::Tensor& pixel_points, const at::Tensor& pixel_valid, int64_t patch_size);

// Per query patch (T of them): the index of the map token (of N) whose point is nearest the
// patch's true point, when within `radius` (T), else N (no match); -1 where the patch has no
// ground truth. patch_points (T, 3), patch_valid (T), map_points (N, 3), map_valid (N): tokens
// without a point are never a target.
at::Tensor matchingTargets(const at::Tensor& patch_points, const at::Tensor& patch_valid, const at::Tensor& map_points,
                           const at::Tensor& map_valid, const at::Tensor& radius);

struct MatchingLossTerm {
  at::Tensor loss;   // scalar, differentiable: mean cross-entropy over patches with a target; 0 if none
  double accuracy = 0;  // share of those patches whose best logit is the target
  int64_t patches = 0;
};
// logits (T, N + 1), targets (T) as matchingTargets gives them.
MatchingLossTerm matchingLoss(const at::Tensor& logits, const at::Tensor& targets);

}  // namespace ffloc
