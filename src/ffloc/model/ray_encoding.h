#pragma once

#include <ATen/core/Tensor.h>

#include <string>
#include <vector>

#include "ffloc/geometry/rays.h"
#include "ffloc/model/layers.h"

namespace ffloc {

// NeRF positional encoding of the last dimension: [x (optional), sin(2^0 pi x), cos(2^0 pi x),
// ..., sin(2^(L-1) pi x), cos(2^(L-1) pi x)], each block as wide as x. Computed in float32.
at::Tensor fourierFeatures(const at::Tensor& x, int64_t num_frequencies, bool include_input = true);

// FastForward's ray encoding (paper, section 3.1): the normalised camera origin and the viewing
// direction of each map token, Fourier-encoded (NeRF's separate frequency counts for positions
// and directions), then an MLP to the encoder width whose output is added to the token.
struct RayEncoderConfig {
  int64_t origin_frequencies = 10;
  int64_t direction_frequencies = 4;
  bool include_input = true;
  int64_t hidden_dim = 0;  // 0: the output width

  int64_t inputDim() const;
};

struct RayEncoder {
  RayEncoderConfig config;
  nn::Linear fc1, fc2;

  RayEncoder() = default;
  RayEncoder(const RayEncoderConfig& config, int64_t out_dim);
  void registerIn(ParameterTable& table, const std::string& prefix);
  // rays: (..., 6) = origin xyz, direction xyz. Output (..., out_dim) in the weights' dtype.
  at::Tensor forward(const at::Tensor& rays) const;
};

// (1, N, 6) float32 tensor of rays (origin, direction), e.g. from patchRays().
at::Tensor rayTensor(const std::vector<Ray>& rays);

}  // namespace ffloc
