#include "ffloc/model/dpt_head.h"

#include <ATen/TensorOperators.h>
#include <ATen/core/grad_mode.h>
#include <ATen/ops/relu.h>

#include "ffloc/model/op_profile.h"
#include "ffloc/model/torch_compat.h"

namespace ffloc {

namespace {

DptHead::ResidualUnit residualUnit(int64_t features) {
  return {nn::Conv2d(features, features, 3, 1, 1), nn::Conv2d(features, features, 3, 1, 1)};
}

void registerUnit(DptHead::ResidualUnit& unit, ParameterTable& table, const std::string& prefix) {
  unit.conv1.registerIn(table, prefix + ".conv1");
  unit.conv2.registerIn(table, prefix + ".conv2");
}

at::Tensor profiledRelu(const at::Tensor& x) {
  const OpScope scope(OpKind::kElementwise);
  return at::relu(x);
}

bool withoutAutograd(const at::Tensor& x) { return !(at::GradMode::is_enabled() && x.requires_grad()); }

// For maps the head has just computed and nobody else holds: in place without autograd, which
// saves a map-sized allocation (the output head's maps are 100 MB at 512x384).
at::Tensor reluOwned(at::Tensor x) {
  const OpScope scope(OpKind::kElementwise);
  if (withoutAutograd(x)) return x.relu_();
  return at::relu(x);
}

at::Tensor addOwned(at::Tensor owned, const at::Tensor& other) {
  const OpScope scope(OpKind::kElementwise);
  if (withoutAutograd(owned) && withoutAutograd(other)) return owned.add_(other);
  return owned + other;
}

at::Tensor applyUnit(const DptHead::ResidualUnit& unit, const at::Tensor& x) {
  return addOwned(unit.conv2.forward(reluOwned(unit.conv1.forward(profiledRelu(x)))), x);
}

at::Tensor upsampleTwice(const at::Tensor& x) {
  const OpScope scope(OpKind::kElementwise);
  return torch_compat::resizeBilinearAlignCorners(x, x.size(2) * 2, x.size(3) * 2);
}

at::Tensor applyFusion(const DptHead::FusionBlock& block, const at::Tensor& first,
                       const at::Tensor* second) {
  at::Tensor out = first;
  if (second) out = addOwned(applyUnit(block.unit1, *second), out);
  out = applyUnit(block.unit2, out);
  return block.out_conv.forward(upsampleTwice(out));
}

void record(TensorTrace* trace, const std::string& prefix, const std::string& name, const at::Tensor& value) {
  if (trace) (*trace)[prefix + "." + name] = value;
}

}  // namespace

DptHead::DptHead(const DptHeadConfig& config, const std::array<int64_t, 4>& dim_tokens) {
  const auto& dims = config.layer_dims;
  const int64_t features = config.feature_dim;
  for (size_t i = 0; i < 4; ++i) project[i] = nn::Conv2d(dim_tokens[i], dims[i], 1);
  // x4 and x2 by transposed convolution, x1, then x1/2 by a strided 3x3 convolution.
  resample[0] = nn::Conv2d(dims[0], dims[0], 4, 4, 0, true, true);
  resample[1] = nn::Conv2d(dims[1], dims[1], 2, 2, 0, true, true);
  resample[3] = nn::Conv2d(dims[3], dims[3], 3, 2, 1);
  for (size_t i = 0; i < 4; ++i) {
    layer_rn[i] = nn::Conv2d(dims[i], features, 3, 1, 1, /*has_bias=*/false);
    refinenet[i] = {residualUnit(features), residualUnit(features), nn::Conv2d(features, features, 1)};
  }
  head0 = nn::Conv2d(features, features / 2, 3, 1, 1);
  head2 = nn::Conv2d(features / 2, config.last_dim, 3, 1, 1);
  head4 = nn::Conv2d(config.last_dim, config.num_channels, 1);
}

void DptHead::registerIn(ParameterTable& table, const std::string& prefix) {
  // state_dict order of the reference: scratch (layer*_rn, their layer_rn.* aliases, refinenets),
  // head, act_postprocess.
  const std::string scratch = prefix + ".scratch.";
  for (size_t i = 0; i < 4; ++i) layer_rn[i].registerIn(table, scratch + "layer" + std::to_string(i + 1) + "_rn");
  for (size_t i = 0; i < 4; ++i) {
    table.addAlias(scratch + "layer_rn." + std::to_string(i) + ".weight",
                   scratch + "layer" + std::to_string(i + 1) + "_rn.weight");
  }
  for (size_t i = 0; i < 4; ++i) {
    const std::string name = scratch + "refinenet" + std::to_string(i + 1);
    refinenet[i].out_conv.registerIn(table, name + ".out_conv");
    registerUnit(refinenet[i].unit1, table, name + ".resConfUnit1");
    registerUnit(refinenet[i].unit2, table, name + ".resConfUnit2");
  }
  head0.registerIn(table, prefix + ".head.0");
  head2.registerIn(table, prefix + ".head.2");
  head4.registerIn(table, prefix + ".head.4");
  for (size_t i = 0; i < 4; ++i) {
    const std::string name = prefix + ".act_postprocess." + std::to_string(i);
    project[i].registerIn(table, name + ".0");
    if (i != 2) resample[i].registerIn(table, name + ".1");
  }
}

at::Tensor DptHead::forward(const std::array<at::Tensor, 4>& tokens, int64_t height, int64_t width,
                            int64_t patch_size, TensorTrace* trace, const std::string& trace_prefix) const {
  const int64_t rows = height / patch_size, cols = width / patch_size;
  std::array<at::Tensor, 4> layers;
  for (size_t i = 0; i < 4; ++i) {
    const at::Tensor& t = tokens[i];
    // (B, N, C) -> (B, C, rows, cols), token n at row n / cols, as a channels-last view without a
    // copy. The whole head then stays channels-last, where oneDNN's convolutions and the bilinear
    // upsampling are fastest (bf16 upsampling: 8.5 ms against 200 ms in NCHW, measured).
    at::Tensor map = t.reshape({t.size(0), rows, cols, t.size(2)}).permute({0, 3, 1, 2});
    map = project[i].forward(map);
    if (i != 2) map = resample[i].forward(map);
    record(trace, trace_prefix, "act_postprocess" + std::to_string(i), map);
    layers[i] = layer_rn[i].forward(map);
    record(trace, trace_prefix, "layer_rn" + std::to_string(i), layers[i]);
  }
  const at::Tensor uncropped = applyFusion(refinenet[3], layers[3], nullptr);
  record(trace, trace_prefix, "refinenet4_uncropped", uncropped);
  // Odd token grids make the x2 path one row/column larger than layer 2: keep the top-left.
  const at::Tensor path4 = uncropped.narrow(2, 0, layers[2].size(2)).narrow(3, 0, layers[2].size(3));
  record(trace, trace_prefix, "path4", path4);
  const at::Tensor path3 = applyFusion(refinenet[2], path4, &layers[2]);
  record(trace, trace_prefix, "path3", path3);
  const at::Tensor path2 = applyFusion(refinenet[1], path3, &layers[1]);
  record(trace, trace_prefix, "path2", path2);
  const at::Tensor path1 = applyFusion(refinenet[0], path2, &layers[0]);
  record(trace, trace_prefix, "path1", path1);
  at::Tensor out = upsampleTwice(head0.forward(path1));
  out = reluOwned(head2.forward(out));  // one full-resolution map alive besides head2's input, not two
  // The output projection keeps its own precision (float32), so depth and confidence, which go
  // through exp, are not rounded to bfloat16.
  out = head4.forward(out.to(head4.weight.scalar_type()));
  record(trace, trace_prefix, "raw", out);
  return out;
}

}  // namespace ffloc
