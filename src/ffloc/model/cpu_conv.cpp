#include "ffloc/model/cpu_conv.h"

#include <ATen/core/grad_mode.h>
#include <ATen/ops/empty.h>

#include <algorithm>

#include "ffloc/model/cpu_gemm.h"
#include "ffloc/model/torch_threads.h"

namespace ffloc {

at::Tensor convolutionTaps(const at::Tensor& weight) { return weight.permute({2, 3, 1, 0}).contiguous(); }

void conv3x3RowsOnThisThread(const std::function<const float*(int64_t)>& source, int64_t rows, int64_t cols, int64_t in, int64_t out,
                             const float* taps, const float* bias, float* dst, int64_t first, int64_t last) {
  for (int64_t y = first; y < last; ++y) {
    float* out_row = dst + (y - first) * cols * out;
    for (int64_t i = 0; i < cols; ++i) {
      for (int64_t j = 0; j < out; ++j) out_row[i * out + j] = bias ? bias[j] : 0.0f;
    }
    for (int64_t dy = 0; dy < 3; ++dy) {
      const int64_t source_row = y + dy - 1;
      if (source_row < 0 || source_row >= rows) continue;  // the zero padding
      const float* in_row = source(source_row);
      for (int64_t dx = 0; dx < 3; ++dx) {
        // Output pixels [begin, end) have their dx neighbour inside the row.
        const int64_t begin = dx == 0 ? 1 : 0, end = dx == 2 ? cols - 1 : cols;
        if (end <= begin) continue;
        sgemmOnThisThread(false, end - begin, out, in, 1.0f, in_row + (begin + dx - 1) * in, in,
                          taps + (dy * 3 + dx) * in * out, out, 1.0f, out_row + begin * out, out);
      }
    }
  }
}

bool cpuConvolutionApplies(const at::Tensor& x, const at::Tensor& weight, int64_t stride, int64_t padding) {
  if (at::GradMode::is_enabled() && (x.requires_grad() || weight.requires_grad())) return false;
  if (!x.is_cpu() || x.scalar_type() != at::kFloat || weight.scalar_type() != at::kFloat || x.dim() != 4 ||
      weight.dim() != 4 || stride != 1) {
    return false;
  }
  const int64_t kernel = weight.size(2);
  return weight.size(3) == kernel && ((kernel == 3 && padding == 1) || (kernel == 1 && padding == 0));
}

at::Tensor cpuConvolution(const at::Tensor& x, const at::Tensor& weight, const at::Tensor& bias) {
  const int64_t batch = x.size(0), in = x.size(1), rows = x.size(2), cols = x.size(3);
  const int64_t out = weight.size(0), kernel = weight.size(2);
  // (B, H, W, C): a no-op for the heads' channels-last maps.
  const at::Tensor pixels = x.permute({0, 2, 3, 1}).contiguous();
  if (kernel == 1) {
    return cpuLinear(pixels, weight.reshape({out, in}), bias, {}).permute({0, 3, 1, 2});
  }
  // taps[dy][dx] is the (C_in, C_out) matrix of one kernel position.
  const at::Tensor taps = convolutionTaps(weight);
  at::Tensor result = at::empty({batch, rows, cols, out}, x.options().memory_format(at::MemoryFormat::Contiguous));
  const float* src = pixels.data_ptr<float>();
  const float* tap = taps.data_ptr<float>();
  const float* b = bias.defined() ? bias.data_ptr<float>() : nullptr;
  float* dst = result.data_ptr<float>();

  const SingleThreadedBlas single_threaded;
  parallelFor(0, batch * rows, 1, [&](int64_t first, int64_t last) {
    // One image at a time: [first, last) may span the end of one and the start of the next.
    while (first < last) {
      const int64_t image = first / rows;
      const int64_t end = std::min(last, (image + 1) * rows);
      const float* image_pixels = src + image * rows * cols * in;
      conv3x3RowsOnThisThread([&](int64_t r) { return image_pixels + r * cols * in; }, rows, cols, in, out, tap, b,
                              dst + first * cols * out, first - image * rows, end - image * rows);
      first = end;
    }
  });
  return result.permute({0, 3, 1, 2});
}

}  // namespace ffloc
