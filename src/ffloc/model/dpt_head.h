#pragma once

#include <ATen/core/Tensor.h>

#include <array>
#include <map>
#include <string>

#include "ffloc/model/dust3r_config.h"
#include "ffloc/model/layers.h"

namespace ffloc {

// Intermediate tensors by name, filled only when a caller asks for them (parity tests, debugging).
using TensorTrace = std::map<std::string, at::Tensor>;

// DUSt3R's DPT head (DPTOutputAdapter_fix with the "regression" output): four token maps are
// reassembled to 1/4, 1/8, 1/16 and 1/32 resolution, fused coarse to fine by refinenets, and
// turned into a (B, 4, H, W) map. Runs in the dtype of its weights (float32 in DUSt3R).
struct DptHead {
  // Residual conv unit: conv2(relu(conv1(relu(x)))) + x.
  struct ResidualUnit {
    nn::Conv2d conv1, conv2;
  };
  // Feature fusion: (first + RCU1(second)) -> RCU2 -> bilinear x2 (align corners) -> out_conv.
  struct FusionBlock {
    ResidualUnit unit1, unit2;
    nn::Conv2d out_conv;
  };

  std::array<nn::Conv2d, 4> project;   // act_postprocess.i.0: 1x1 to layer_dims[i]
  std::array<nn::Conv2d, 4> resample;  // act_postprocess.i.1 (none for i = 2)
  std::array<nn::Conv2d, 4> layer_rn;  // scratch.layer{i+1}_rn, 3x3 no bias
  std::array<FusionBlock, 4> refinenet;
  nn::Conv2d head0, head2, head4;

  DptHead() = default;
  // dim_tokens: widths of the four hooked token maps (encoder, then decoder x3).
  DptHead(const DptHeadConfig& config, const std::array<int64_t, 4>& dim_tokens);
  void registerIn(ParameterTable& table, const std::string& prefix);

  // tokens: the four hooked (B, N, C_i) maps of an image of height x width pixels, with
  // N = (height / patch) * (width / patch). Returns the raw (B, 4, height, width) output.
  // Trace names are "<prefix>.act_postprocess0", "<prefix>.path4", ... as in the fixtures.
  at::Tensor forward(const std::array<at::Tensor, 4>& tokens, int64_t height, int64_t width,
                     int64_t patch_size, TensorTrace* trace = nullptr,
                     const std::string& trace_prefix = "") const;
};

}  // namespace ffloc
