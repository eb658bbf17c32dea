#include "ffloc/model/dpt_head.h"

#include <ATen/TensorOperators.h>
#include <ATen/core/grad_mode.h>
#include <ATen/ops/empty.h>
#include <ATen/ops/relu.h>

#include <algorithm>
#include <vector>

#include "ffloc/model/cpu_conv.h"
#include "ffloc/model/cpu_gemm.h"
#include "ffloc/model/op_profile.h"
#include "ffloc/model/torch_compat.h"
#include "ffloc/model/torch_threads.h"

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

// Output rows per band of the banded output head: a band's upsampled input (band + 2 rows) and
// head.2 output at 512 pixels x 128 channels are ~9 MB each.
constexpr int64_t kOutputBandRows = 16;

// Whether the output head can run banded: float32 CPU maps and weights, no autograd.
bool bandedOutputHeadApplies(const at::Tensor& half, const nn::Conv2d& head2, const nn::Conv2d& head4) {
  return withoutAutograd(half) && half.is_cpu() && half.scalar_type() == at::kFloat &&
         head2.weight.scalar_type() == at::kFloat && head4.weight.scalar_type() == at::kFloat &&
         cpuConvolutionApplies(half, head2.weight, head2.stride, head2.padding) && head4.kernel == 1 &&
         !head2.weight.requires_grad() && !head4.weight.requires_grad();
}

// The output head after head.0: bilinear x2 with align corners, head.2 (3x3), ReLU, head.4
// (1x1 to the 4 raw channels), computed in bands of output rows, one band at a time per thread,
// with the band's upsampled rows made on the fly. No full-resolution map of head.2's width
// exists: at 512x384 those are 100 MB each, and the unbanded head holds two (the largest part
// of the network's peak memory besides the weights). The interpolation is ATen's (float
// source positions scale * index with scale = (in - 1) / (out - 1), the same weighted sums).
at::Tensor bandedOutputHead(const at::Tensor& half, const nn::Conv2d& head2, const nn::Conv2d& head4) {
  const int64_t batch = half.size(0), channels = half.size(1), in_rows = half.size(2), in_cols = half.size(3);
  const int64_t rows = 2 * in_rows, cols = 2 * in_cols;
  const int64_t hidden = head2.out, outputs = head4.out;
  const at::Tensor source = half.permute({0, 2, 3, 1}).contiguous();  // (B, h, w, C)
  const at::Tensor taps = convolutionTaps(head2.weight);
  const at::Tensor projection = head4.weight.reshape({outputs, hidden}).contiguous();
  at::Tensor raw = at::empty({batch, rows, cols, outputs}, half.options().memory_format(at::MemoryFormat::Contiguous));
  const float scale_y = rows > 1 ? static_cast<float>(in_rows - 1) / static_cast<float>(rows - 1) : 0.0f;
  const float scale_x = cols > 1 ? static_cast<float>(in_cols - 1) / static_cast<float>(cols - 1) : 0.0f;
  std::vector<int64_t> x0(cols), x1(cols);
  std::vector<float> wx0(cols), wx1(cols);
  for (int64_t x = 0; x < cols; ++x) {
    const float position = scale_x * static_cast<float>(x);
    x0[x] = static_cast<int64_t>(position);
    x1[x] = x0[x] + (x0[x] < in_cols - 1 ? 1 : 0);
    wx1[x] = position - static_cast<float>(x0[x]);
    wx0[x] = 1.0f - wx1[x];
  }
  const float* src = source.data_ptr<float>();
  const float* tap = taps.data_ptr<float>();
  const float* bias2 = head2.bias.defined() ? head2.bias.data_ptr<float>() : nullptr;
  const float* weight4 = projection.data_ptr<float>();
  const float* bias4 = head4.bias.defined() ? head4.bias.data_ptr<float>() : nullptr;
  float* dst = raw.data_ptr<float>();
  const int64_t bands = (rows + kOutputBandRows - 1) / kOutputBandRows;

  const SingleThreadedBlas single_threaded;
  const OpScope scope(OpKind::kConvolution, 2.0 * static_cast<double>(batch * rows * cols) *
                                                static_cast<double>(9 * channels * hidden + hidden * outputs));
  parallelFor(0, batch * bands, 1, [&](int64_t first, int64_t last) {
    std::vector<float> upsampled(static_cast<size_t>((kOutputBandRows + 2) * cols * channels));
    std::vector<float> activations(static_cast<size_t>(kOutputBandRows * cols * hidden));
    for (int64_t task = first; task < last; ++task) {
      const int64_t image = task / bands, band = task % bands;
      const int64_t y_begin = band * kOutputBandRows, y_end = std::min(rows, y_begin + kOutputBandRows);
      const int64_t up_begin = std::max<int64_t>(0, y_begin - 1), up_end = std::min(rows, y_end + 1);
      const float* image_source = src + image * in_rows * in_cols * channels;
      for (int64_t y = up_begin; y < up_end; ++y) {
        const float position = scale_y * static_cast<float>(y);
        const int64_t y0 = static_cast<int64_t>(position);
        const int64_t y1 = y0 + (y0 < in_rows - 1 ? 1 : 0);
        const float wy1 = position - static_cast<float>(y0), wy0 = 1.0f - wy1;
        const float* row0 = image_source + y0 * in_cols * channels;
        const float* row1 = image_source + y1 * in_cols * channels;
        float* out_row = upsampled.data() + (y - up_begin) * cols * channels;
        for (int64_t x = 0; x < cols; ++x) {
          const float* a = row0 + x0[x] * channels;
          const float* b = row0 + x1[x] * channels;
          const float* c = row1 + x0[x] * channels;
          const float* d = row1 + x1[x] * channels;
          float* o = out_row + x * channels;
          for (int64_t k = 0; k < channels; ++k) {
            o[k] = wy0 * (wx0[x] * a[k] + wx1[x] * b[k]) + wy1 * (wx0[x] * c[k] + wx1[x] * d[k]);
          }
        }
      }
      conv3x3RowsOnThisThread([&](int64_t r) { return upsampled.data() + (r - up_begin) * cols * channels; }, rows,
                              cols, channels, hidden, tap, bias2, activations.data(), y_begin, y_end);
      const int64_t pixels = (y_end - y_begin) * cols;
      for (int64_t i = 0; i < pixels * hidden; ++i) activations[i] = std::max(activations[i], 0.0f);
      float* raw_rows = dst + (image * rows + y_begin) * cols * outputs;
      for (int64_t p = 0; p < pixels; ++p) {
        for (int64_t j = 0; j < outputs; ++j) raw_rows[p * outputs + j] = bias4 ? bias4[j] : 0.0f;
      }
      sgemmOnThisThread(true, pixels, outputs, hidden, 1.0f, activations.data(), hidden, weight4, hidden, 1.0f,
                        raw_rows, outputs);
    }
  });
  return raw.permute({0, 3, 1, 2});
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
  at::Tensor out = head0.forward(path1);
  if (bandedOutputHeadApplies(out, head2, head4)) {
    out = bandedOutputHead(out, head2, head4);
    record(trace, trace_prefix, "raw", out);
    return out;
  }
  out = reluOwned(head2.forward(upsampleTwice(out)));  // one full-resolution map alive besides head2's input, not two
  // The output projection keeps its own precision (float32), so depth and confidence, which go
  // through exp, are not rounded to bfloat16.
  out = head4.forward(out.to(head4.weight.scalar_type()));
  record(trace, trace_prefix, "raw", out);
  return out;
}

}  // namespace ffloc
