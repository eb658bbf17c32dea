#include "ffloc/model/dpt_head.h"

#include <ATen/TensorOperators.h>
#include <ATen/core/grad_mode.h>
#include <ATen/ops/empty.h>
#include <ATen/ops/relu.h>

#include <algorithm>
#include <utility>
#include <vector>

#include "ffloc/model/bfloat16_kernels.h"
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

// Output rows per band of the banded kernels below: a band's upsampled input (band + 2 rows) and
// head.2 output at 512 pixels x 128 channels are ~9 MB each.
constexpr int64_t kOutputBandRows = 16;

bool isFloatCpu(const at::Tensor& x) { return x.is_cpu() && x.scalar_type() == at::kFloat; }

// Whether the banded float32 kernels below serve `conv` on x: float32 CPU maps and weights, or
// bf16 maps computed in float32 (bfloat16_kernels.h), without autograd; stride 1 and a 1x1
// kernel, or a 3x3 one with padding 1.
bool bandedKernelsServe(const at::Tensor& x, const nn::Conv2d& conv, int64_t kernel) {
  if (!withoutAutograd(x) || conv.weight.requires_grad() || !conv.weight.is_cpu() || x.dim() != 4) return false;
  if (conv.transposed || conv.stride != 1 || conv.kernel != kernel || conv.padding != (kernel == 3 ? 1 : 0)) return false;
  return (isFloatCpu(x) && isFloatCpu(conv.weight)) || computesInFloat32(x);
}

// Whether the output head can run banded.
bool bandedOutputHeadApplies(const at::Tensor& half, const nn::Conv2d& head2, const nn::Conv2d& head4) {
  return bandedKernelsServe(half, head2, 3) && bandedKernelsServe(half, head4, 1);
}

// Whether a fusion block's 1x1 out_conv after the x2 upsampling can run banded.
bool bandedUpsampledProjectionApplies(const at::Tensor& x, const nn::Conv2d& conv) {
  return bandedKernelsServe(x, conv, 1);
}

// Rows of the bilinear x2 upsampling with align corners of channels-last images (B, h, w, C),
// made on demand. The interpolation is ATen's (float source positions scale * index with
// scale = (in - 1) / (out - 1), the same weighted sums).
class UpsampledRows {
 public:
  explicit UpsampledRows(const at::Tensor& channels_last)
      : source_(channels_last),
        in_rows_(channels_last.size(1)),
        in_cols_(channels_last.size(2)),
        channels_(channels_last.size(3)),
        x0_(2 * in_cols_),
        x1_(2 * in_cols_),
        wx0_(2 * in_cols_),
        wx1_(2 * in_cols_) {
    const int64_t rows = 2 * in_rows_, cols = 2 * in_cols_;
    scale_y_ = rows > 1 ? static_cast<float>(in_rows_ - 1) / static_cast<float>(rows - 1) : 0.0f;
    const float scale_x = cols > 1 ? static_cast<float>(in_cols_ - 1) / static_cast<float>(cols - 1) : 0.0f;
    for (int64_t x = 0; x < cols; ++x) {
      const float position = scale_x * static_cast<float>(x);
      x0_[x] = static_cast<int64_t>(position);
      x1_[x] = x0_[x] + (x0_[x] < in_cols_ - 1 ? 1 : 0);
      wx1_[x] = position - static_cast<float>(x0_[x]);
      wx0_[x] = 1.0f - wx1_[x];
    }
  }

  int64_t rows() const { return 2 * in_rows_; }
  int64_t cols() const { return 2 * in_cols_; }
  int64_t channels() const { return channels_; }

  // Row y of image `image` into dst (cols() x channels() floats).
  void row(int64_t image, int64_t y, float* dst) const {
    const float position = scale_y_ * static_cast<float>(y);
    const int64_t y0 = static_cast<int64_t>(position);
    const int64_t y1 = y0 + (y0 < in_rows_ - 1 ? 1 : 0);
    const float wy1 = position - static_cast<float>(y0), wy0 = 1.0f - wy1;
    const float* image_source = source_.data_ptr<float>() + image * in_rows_ * in_cols_ * channels_;
    const float* row0 = image_source + y0 * in_cols_ * channels_;
    const float* row1 = image_source + y1 * in_cols_ * channels_;
    for (int64_t x = 0; x < cols(); ++x) {
      const float* a = row0 + x0_[x] * channels_;
      const float* b = row0 + x1_[x] * channels_;
      const float* c = row1 + x0_[x] * channels_;
      const float* d = row1 + x1_[x] * channels_;
      float* o = dst + x * channels_;
      for (int64_t k = 0; k < channels_; ++k) {
        o[k] = wy0 * (wx0_[x] * a[k] + wx1_[x] * b[k]) + wy1 * (wx0_[x] * c[k] + wx1_[x] * d[k]);
      }
    }
  }

 private:
  at::Tensor source_;
  int64_t in_rows_, in_cols_, channels_;
  float scale_y_ = 0.0f;
  std::vector<int64_t> x0_, x1_;
  std::vector<float> wx0_, wx1_;
};

// dst (pixels x out, row-major) = bias + src (pixels x in) weight^T, on the calling thread.
void projectPixels(const float* src, int64_t pixels, int64_t in, int64_t out, const float* weight, const float* bias,
                   float* dst) {
  for (int64_t p = 0; p < pixels; ++p) {
    for (int64_t j = 0; j < out; ++j) dst[p * out + j] = bias ? bias[j] : 0.0f;
  }
  sgemmOnThisThread(true, pixels, out, in, 1.0f, src, in, weight, in, 1.0f, dst, out);
}

// A fusion block's last step, out_conv (1x1) of the x2 upsampled map, computed in bands of
// output rows with each band's upsampled rows made on the fly: the upsampled map never exists
// whole (12 MiB for the second finest block at 512x384, 48 MiB for the finest when a trace
// asks for its output; untraced, the finest runs in bandedFinestPath).
at::Tensor bandedUpsampledProjection(const at::Tensor& map, const nn::Conv2d& stored_conv) {
  const at::Tensor x = widened(map);
  const nn::Conv2d conv = stored_conv.withFloat32Weights();
  const UpsampledRows upsampled(x.permute({0, 2, 3, 1}).contiguous());
  const int64_t batch = x.size(0), rows = upsampled.rows(), cols = upsampled.cols();
  const int64_t in = upsampled.channels(), out = conv.out;
  const at::Tensor weight = conv.weight.reshape({out, in}).contiguous();
  at::Tensor result = at::empty({batch, rows, cols, out}, x.options().memory_format(at::MemoryFormat::Contiguous));
  const float* w = weight.data_ptr<float>();
  const float* bias = conv.bias.defined() ? conv.bias.data_ptr<float>() : nullptr;
  float* dst = result.data_ptr<float>();
  const int64_t bands = (rows + kOutputBandRows - 1) / kOutputBandRows;

  const SingleThreadedBlas single_threaded;
  const OpScope scope(OpKind::kConvolution, 2.0 * static_cast<double>(batch * rows * cols * in * out));
  parallelFor(0, batch * bands, 1, [&](int64_t first, int64_t last) {
    std::vector<float> band(static_cast<size_t>(kOutputBandRows * cols * in));
    for (int64_t task = first; task < last; ++task) {
      const int64_t image = task / bands;
      const int64_t y_begin = task % bands * kOutputBandRows, y_end = std::min(rows, y_begin + kOutputBandRows);
      for (int64_t y = y_begin; y < y_end; ++y) upsampled.row(image, y, band.data() + (y - y_begin) * cols * in);
      projectPixels(band.data(), (y_end - y_begin) * cols, in, out, w, bias,
                    dst + (image * rows + y_begin) * cols * out);
    }
  });
  return narrowed(result.permute({0, 3, 1, 2}), map.scalar_type());
}

// A fusion block up to its out_conv: unit2(first + unit1(second)), or unit2(first) for the
// coarsest block (`second` undefined). Both maps are released as soon as they are read.
at::Tensor fuseUnits(const DptHead::FusionBlock& block, at::Tensor first, at::Tensor second) {
  at::Tensor out = std::move(first);
  if (second.defined()) out = addOwned(applyUnit(block.unit1, std::exchange(second, {})), out);
  return applyUnit(block.unit2, out);
}

// A fusion block's last step: out_conv of the x2 upsampled map.
at::Tensor upsampledProjection(const nn::Conv2d& out_conv, at::Tensor x) {
  if (bandedUpsampledProjectionApplies(x, out_conv)) return bandedUpsampledProjection(std::exchange(x, {}), out_conv);
  return out_conv.forward(upsampleTwice(std::exchange(x, {})));
}

// Whether head.0 can read the finest fusion block's out_conv rows as they are made: float32
// CPU, no autograd.
bool bandedFinestPathApplies(const at::Tensor& x, const nn::Conv2d& out_conv, const nn::Conv2d& head0) {
  return bandedUpsampledProjectionApplies(x, out_conv) && bandedKernelsServe(x, head0, 3);
}

// head.0 (3x3) of the finest fusion block's last step (out_conv of the x2 upsampled map), in
// bands of head.0's output rows: each band's out_conv rows, with the 3x3 halo above and below,
// are made on the fly from upsampled rows, so the finest path (48 MiB at 512x384: 256 channels
// at 256x192) never exists whole. The two halo rows of a band are made again by its neighbour:
// 1/8 more of out_conv's products (0.8 of the head's 187 GFLOP).
at::Tensor bandedFinestPath(const at::Tensor& map, const nn::Conv2d& stored_out_conv, const nn::Conv2d& stored_head0) {
  const at::Tensor x = widened(map);
  const nn::Conv2d out_conv = stored_out_conv.withFloat32Weights(), head0 = stored_head0.withFloat32Weights();
  const UpsampledRows upsampled(x.permute({0, 2, 3, 1}).contiguous());
  const int64_t batch = x.size(0), rows = upsampled.rows(), cols = upsampled.cols();
  const int64_t in = upsampled.channels(), mid = out_conv.out, out = head0.out;
  const at::Tensor projection = out_conv.weight.reshape({mid, in}).contiguous();
  const at::Tensor taps = convolutionTaps(head0.weight);
  at::Tensor result = at::empty({batch, rows, cols, out}, x.options().memory_format(at::MemoryFormat::Contiguous));
  const float* w = projection.data_ptr<float>();
  const float* bias = out_conv.bias.defined() ? out_conv.bias.data_ptr<float>() : nullptr;
  const float* tap = taps.data_ptr<float>();
  const float* bias0 = head0.bias.defined() ? head0.bias.data_ptr<float>() : nullptr;
  float* dst = result.data_ptr<float>();
  const int64_t bands = (rows + kOutputBandRows - 1) / kOutputBandRows;

  const SingleThreadedBlas single_threaded;
  const OpScope scope(OpKind::kConvolution,
                      2.0 * static_cast<double>(batch * rows * cols) * static_cast<double>(in * mid + 9 * mid * out));
  parallelFor(0, batch * bands, 1, [&](int64_t first, int64_t last) {
    std::vector<float> upsampled_row(static_cast<size_t>(cols * in));
    std::vector<float> path(static_cast<size_t>((kOutputBandRows + 2) * cols * mid));
    for (int64_t task = first; task < last; ++task) {
      const int64_t image = task / bands;
      const int64_t y_begin = task % bands * kOutputBandRows, y_end = std::min(rows, y_begin + kOutputBandRows);
      const int64_t path_begin = std::max<int64_t>(0, y_begin - 1), path_end = std::min(rows, y_end + 1);
      for (int64_t y = path_begin; y < path_end; ++y) {
        upsampled.row(image, y, upsampled_row.data());
        projectPixels(upsampled_row.data(), cols, in, mid, w, bias, path.data() + (y - path_begin) * cols * mid);
      }
      conv3x3RowsOnThisThread([&](int64_t r) { return path.data() + (r - path_begin) * cols * mid; }, rows, cols,
                              mid, out, tap, bias0, dst + (image * rows + y_begin) * cols * out, y_begin, y_end);
    }
  });
  return narrowed(result.permute({0, 3, 1, 2}), map.scalar_type());
}

// The output head after head.0: bilinear x2 with align corners, head.2 (3x3), ReLU, head.4
// (1x1 to the 4 raw channels), computed in bands of output rows, one band at a time per thread,
// with the band's upsampled rows made on the fly. No full-resolution map of head.2's width
// exists: at 512x384 those are 100 MB each, and the unbanded head holds two (the largest part
// of the network's peak memory besides the weights).
at::Tensor bandedOutputHead(const at::Tensor& stored_half, const nn::Conv2d& stored_head2, const nn::Conv2d& stored_head4) {
  const at::Tensor half = widened(stored_half);
  const nn::Conv2d head2 = stored_head2.withFloat32Weights(), head4 = stored_head4.withFloat32Weights();
  const UpsampledRows upsampled(half.permute({0, 2, 3, 1}).contiguous());
  const int64_t batch = half.size(0), rows = upsampled.rows(), cols = upsampled.cols();
  const int64_t channels = upsampled.channels(), hidden = head2.out, outputs = head4.out;
  const at::Tensor taps = convolutionTaps(head2.weight);
  const at::Tensor projection = head4.weight.reshape({outputs, hidden}).contiguous();
  at::Tensor raw = at::empty({batch, rows, cols, outputs}, half.options().memory_format(at::MemoryFormat::Contiguous));
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
    std::vector<float> band(static_cast<size_t>((kOutputBandRows + 2) * cols * channels));
    std::vector<float> activations(static_cast<size_t>(kOutputBandRows * cols * hidden));
    for (int64_t task = first; task < last; ++task) {
      const int64_t image = task / bands;
      const int64_t y_begin = task % bands * kOutputBandRows, y_end = std::min(rows, y_begin + kOutputBandRows);
      const int64_t up_begin = std::max<int64_t>(0, y_begin - 1), up_end = std::min(rows, y_end + 1);
      for (int64_t y = up_begin; y < up_end; ++y) upsampled.row(image, y, band.data() + (y - up_begin) * cols * channels);
      conv3x3RowsOnThisThread([&](int64_t r) { return band.data() + (r - up_begin) * cols * channels; }, rows,
                              cols, channels, hidden, tap, bias2, activations.data(), y_begin, y_end);
      const int64_t pixels = (y_end - y_begin) * cols;
      for (int64_t i = 0; i < pixels * hidden; ++i) activations[i] = std::max(activations[i], 0.0f);
      projectPixels(activations.data(), pixels, hidden, outputs, weight4, bias4,
                    dst + (image * rows + y_begin) * cols * outputs);
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
  // Each map is dropped as soon as the next step has read it (the finest are 12-48 MiB at
  // 512x384); a trace keeps its own references.
  at::Tensor path = upsampledProjection(refinenet[3].out_conv, fuseUnits(refinenet[3], std::exchange(layers[3], {}), {}));
  record(trace, trace_prefix, "refinenet4_uncropped", path);
  // Odd token grids make the x2 path one row/column larger than layer 2: keep the top-left.
  path = path.narrow(2, 0, layers[2].size(2)).narrow(3, 0, layers[2].size(3));
  record(trace, trace_prefix, "path4", path);
  for (size_t level = 2; level > 0; --level) {
    path = upsampledProjection(refinenet[level].out_conv,
                               fuseUnits(refinenet[level], std::exchange(path, {}), std::exchange(layers[level], {})));
    record(trace, trace_prefix, "path" + std::to_string(level + 1), path);
  }
  path = fuseUnits(refinenet[0], std::exchange(path, {}), std::exchange(layers[0], {}));
  at::Tensor out;
  // A trace records path1, which the banded kernel never makes whole.
  if (!trace && bandedFinestPathApplies(path, refinenet[0].out_conv, head0)) {
    out = bandedFinestPath(std::exchange(path, {}), refinenet[0].out_conv, head0);
  } else {
    path = upsampledProjection(refinenet[0].out_conv, std::exchange(path, {}));
    record(trace, trace_prefix, "path1", path);
    out = head0.forward(std::exchange(path, {}));
  }
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
