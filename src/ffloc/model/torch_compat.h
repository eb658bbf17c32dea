#pragma once

// The few libtorch calls whose spelling differs between Debian's libtorch 1.13 (CPU) and the
// libtorch of PyTorch 2.x (CUDA builds). Everything else in the model module uses API that is
// identical in both.

#include <ATen/TensorOperators.h>
#include <ATen/core/Tensor.h>
#include <ATen/ops/matmul.h>
#include <ATen/ops/softmax.h>
#include <ATen/ops/upsample_bilinear2d.h>
#include <torch/version.h>

#include "ffloc/model/op_profile.h"
#include "ffloc/model/softmax_kernel.h"

#include <cmath>
#include <optional>
#include <vector>

#if TORCH_VERSION_MAJOR > 2 || (TORCH_VERSION_MAJOR == 2 && TORCH_VERSION_MINOR >= 1)
#include <ATen/ops/scaled_dot_product_attention.h>
#define FFLOC_TORCH_HAS_SDPA 1
#else
#define FFLOC_TORCH_HAS_SDPA 0
#endif

namespace ffloc::torch_compat {

// c10::optional is std::optional from PyTorch 2.5 on, and newer headers may not declare
// c10::nullopt; 1.13's c10::optional takes only c10::nullopt.
#if TORCH_VERSION_MAJOR > 2 || (TORCH_VERSION_MAJOR == 2 && TORCH_VERSION_MINOR >= 5)
inline constexpr auto kNoValue = std::nullopt;
#else
inline constexpr auto kNoValue = c10::nullopt;
#endif

// Bilinear resize to exactly `height` x `width` with align_corners=True. With align_corners the
// scale factors play no part in the sampling positions, so leaving them unset is exact. Both
// optional scales are passed explicitly: in 2.x a shorter call is ambiguous with the vec
// overload.
inline at::Tensor resizeBilinearAlignCorners(const at::Tensor& input, int64_t height, int64_t width) {
  const std::vector<int64_t> size = {height, width};
  return at::upsample_bilinear2d(input, at::IntArrayRef(size), /*align_corners=*/true, kNoValue, kNoValue);
}

// softmax(q k^T * head_dim^-0.5) v for (B, heads, N, head_dim) tensors. On CUDA with PyTorch
// >= 2.1 the fused kernel is used. On CPU the scale is applied to q (N x head_dim values) rather
// than to the N x M scores, which differs from the reference's order only in the last float bits.
// Without autograd the softmax overwrites the scores with the vectorised kernel: at 768 x 768
// tokens and 16 heads each saved pass over the scores is ~10 ms per block on one core (measured,
// docs/benchmarks.md). (One head at a time, to keep the scores in L2, was 30 % slower overall.)
inline at::Tensor attention(const at::Tensor& q, const at::Tensor& k, const at::Tensor& v) {
  const double scale = std::pow(static_cast<double>(q.size(-1)), -0.5);
  const OpScope scope(OpKind::kAttention, 4.0 * static_cast<double>(q.numel()) * static_cast<double>(k.size(-2)));
#if FFLOC_TORCH_HAS_SDPA
  if (q.is_cuda()) {
    return at::scaled_dot_product_attention(q, k, v, /*attn_mask=*/{}, /*dropout_p=*/0.0,
                                            /*is_causal=*/false, scale);
  }
#endif
  at::Tensor scores = at::matmul(q * scale, k.transpose(-2, -1));
  if (scores.requires_grad()) return at::matmul(at::softmax(scores, -1), v);
  softmaxLastDimInPlace(scores);
  return at::matmul(scores, v);
}

}  // namespace ffloc::torch_compat
