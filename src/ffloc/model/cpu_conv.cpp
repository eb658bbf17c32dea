#include "ffloc/model/cpu_conv.h"

#include <ATen/Parallel.h>
#include <ATen/core/grad_mode.h>
#include <ATen/ops/empty.h>

#include "ffloc/model/cpu_gemm.h"

namespace ffloc {

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
  const at::Tensor taps = weight.permute({2, 3, 1, 0}).contiguous();
  at::Tensor result = at::empty({batch, rows, cols, out}, x.options().memory_format(at::MemoryFormat::Contiguous));
  const float* src = pixels.data_ptr<float>();
  const float* tap = taps.data_ptr<float>();
  const float* b = bias.defined() ? bias.data_ptr<float>() : nullptr;
  float* dst = result.data_ptr<float>();

  const SingleThreadedBlas single_threaded;
  at::parallel_for(0, batch * rows, 1, [&](int64_t first, int64_t last) {
    for (int64_t task = first; task < last; ++task) {
      const int64_t image = task / rows, y = task % rows;
      float* out_row = dst + task * cols * out;
      for (int64_t i = 0; i < cols; ++i) {
        for (int64_t j = 0; j < out; ++j) out_row[i * out + j] = b ? b[j] : 0.0f;
      }
      for (int64_t dy = 0; dy < 3; ++dy) {
        const int64_t source_row = y + dy - 1;
        if (source_row < 0 || source_row >= rows) continue;  // the zero padding
        const float* in_row = src + (image * rows + source_row) * cols * in;
        for (int64_t dx = 0; dx < 3; ++dx) {
          // Output pixels [begin, end) have their dx neighbour inside the row.
          const int64_t begin = dx == 0 ? 1 : 0, end = dx == 2 ? cols - 1 : cols;
          if (end <= begin) continue;
          sgemmOnThisThread(false, end - begin, out, in, 1.0f, in_row + (begin + dx - 1) * in, in,
                            tap + (dy * 3 + dx) * in * out, out, 1.0f, out_row + begin * out, out);
        }
      }
    }
  });
  return result.permute({0, 3, 1, 2});
}

}  // namespace ffloc
