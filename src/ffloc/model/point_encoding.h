#pragma once

#include <ATen/core/Tensor.h>

#include <string>

#include "ffloc/model/layers.h"

namespace ffloc {

// The 3D point a map token carries when its mapping frame has depth (or a triangulated point),
// in the normalised scene frame: contracted into [-1, 1] (mip-NeRF 360's contraction, halved:
// |x| <= 1 stays linear, the rest of space folds into the shell up to 2), Fourier-encoded with a
// few octaves (2^0 pi .. 2^(L-1) pi; ten octaves up to 2^9 pi would alias a quantity in [-1, 1]),
// then an MLP to the token width. Its output is added to the token beside the ray encoding.
struct PointEncoderConfig {
  int64_t frequencies = 0;  // 0: the model has no point encoder
  int64_t hidden_dim = 0;   // 0: the output width

  bool enabled() const { return frequencies > 0; }
  int64_t inputDim() const { return 3 * (1 + 2 * frequencies); }
};

// (..., 3) -> (..., 3) in [-1, 1].
at::Tensor contractPoints(const at::Tensor& points);

struct PointEncoder {
  PointEncoderConfig config;
  nn::Linear fc1, fc2;

  PointEncoder() = default;
  PointEncoder(const PointEncoderConfig& config, int64_t out_dim);
  void registerIn(ParameterTable& table, const std::string& prefix);
  // points (..., 3) float32, valid (...) bool: the encoding of valid points, 0 elsewhere (a token
  // without a point keeps only its ray, as in the paper). Output in the weights' dtype.
  at::Tensor forward(const at::Tensor& points, const at::Tensor& valid) const;
};

}  // namespace ffloc
