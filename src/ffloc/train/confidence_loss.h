#pragma once

#include <ATen/core/Tensor.h>

namespace ffloc {

// One set's term of the paper's Eq. 2 (DUSt3R's confidence-aware regression loss):
// mean over valid elements i of C_i ||X_i - Xgt_i|| - alpha log C_i.
struct ConfidenceLossTerm {
  at::Tensor loss;   // scalar, differentiable; 0 when no element is valid
  at::Tensor error;  // scalar, detached mean ||X - Xgt|| over valid elements (normalised units)
  int64_t valid = 0;
};

// points, truth: (..., 3); confidence, valid: (...), confidence >= 1 as the heads produce it.
// Normalising per set keeps the query's ~H*W pixels from drowning the map's N tokens, as
// DUSt3R normalises per view.
ConfidenceLossTerm confidenceLoss(const at::Tensor& points, const at::Tensor& confidence, const at::Tensor& truth,
                                  const at::Tensor& valid, double alpha);

}  // namespace ffloc
