#pragma once

// Functional building blocks of the DUSt3R/CroCo transformer: each holds its parameter tensors
// under their PyTorch names and computes what the reference modules compute. float32 on the CPU
// without autograd takes the fused kernels (cpu_gemm.h, cpu_attention.h, in-place RoPE), and so
// does bfloat16 on CPUs without native bf16, widened layer by layer (bfloat16_kernels.h);
// everything else applies the reference's ATen ops. `residual` arguments add the block's skip
// connection to the layer's output in the same pass.

#include <ATen/core/Tensor.h>

#include <string>

#include "ffloc/model/parameter_table.h"
#include "ffloc/model/rope2d.h"

namespace ffloc::nn {

struct Linear {
  int64_t in = 0, out = 0;
  at::Tensor weight, bias;

  Linear() = default;
  Linear(int64_t in, int64_t out) : in(in), out(out) {}
  void registerIn(ParameterTable& table, const std::string& prefix);
  // x weight^T + bias, plus `residual` when it is defined (a residual connection in one pass).
  at::Tensor forward(const at::Tensor& x, const at::Tensor& residual = {}) const;
  // This layer with float32 copies of its bf16 tensors (bfloat16_kernels.h).
  Linear withFloat32Weights() const;
};

struct LayerNorm {
  int64_t dim = 0;
  double eps = 1e-6;
  at::Tensor weight, bias;

  LayerNorm() = default;
  LayerNorm(int64_t dim, double eps) : dim(dim), eps(eps) {}
  void registerIn(ParameterTable& table, const std::string& prefix);
  at::Tensor forward(const at::Tensor& x) const;
};

// Conv2d (or ConvTranspose2d when `transposed`) with a square kernel.
struct Conv2d {
  int64_t in = 0, out = 0, kernel = 1, stride = 1, padding = 0;
  bool has_bias = true;
  bool transposed = false;
  at::Tensor weight, bias;

  Conv2d() = default;
  Conv2d(int64_t in, int64_t out, int64_t kernel, int64_t stride = 1, int64_t padding = 0,
         bool has_bias = true, bool transposed = false)
      : in(in), out(out), kernel(kernel), stride(stride), padding(padding), has_bias(has_bias),
        transposed(transposed) {}
  void registerIn(ParameterTable& table, const std::string& prefix);
  at::Tensor forward(const at::Tensor& x) const;
  // This layer with float32 copies of its bf16 tensors (bfloat16_kernels.h).
  Conv2d withFloat32Weights() const;
};

// fc1 -> exact (erf) GELU -> fc2.
struct Mlp {
  Linear fc1, fc2;

  Mlp() = default;
  Mlp(int64_t dim, int64_t hidden) : fc1(dim, hidden), fc2(hidden, dim) {}
  void registerIn(ParameterTable& table, const std::string& prefix);
  at::Tensor forward(const at::Tensor& x, const at::Tensor& residual = {}) const;
};

// Self-attention with one qkv projection laid out [q | k | v], heads contiguous inside each.
struct Attention {
  int64_t num_heads = 1;
  Linear qkv, proj;

  Attention() = default;
  Attention(int64_t dim, int64_t num_heads) : num_heads(num_heads), qkv(dim, 3 * dim), proj(dim, dim) {}
  void registerIn(ParameterTable& table, const std::string& prefix);
  at::Tensor forward(const at::Tensor& x, const RopeFactors& rope, const at::Tensor& residual = {}) const;
};

// Cross-attention: queries from one stream, keys and values from the other (token counts may
// differ); RoPE with each stream's own positions.
struct CrossAttention {
  int64_t num_heads = 1;
  Linear projq, projk, projv, proj;

  CrossAttention() = default;
  CrossAttention(int64_t dim, int64_t num_heads)
      : num_heads(num_heads), projq(dim, dim), projk(dim, dim), projv(dim, dim), proj(dim, dim) {}
  void registerIn(ParameterTable& table, const std::string& prefix);
  at::Tensor forward(const at::Tensor& query, const at::Tensor& key_value, const RopeFactors& query_rope,
                     const RopeFactors& key_rope, const at::Tensor& residual = {}) const;
};

// Pre-norm ViT block: x += attn(norm1(x)); x += mlp(norm2(x)).
struct EncoderBlock {
  LayerNorm norm1, norm2;
  Attention attn;
  Mlp mlp;

  EncoderBlock() = default;
  EncoderBlock(int64_t dim, int64_t num_heads, int64_t mlp_ratio, double eps)
      : norm1(dim, eps), norm2(dim, eps), attn(dim, num_heads), mlp(dim, dim * mlp_ratio) {}
  void registerIn(ParameterTable& table, const std::string& prefix);
  at::Tensor forward(const at::Tensor& x, const RopeFactors& rope) const;
};

// CroCo decoder block: self-attention, then cross-attention to the normalised other stream y,
// then the MLP. Returns the updated x; y is read only.
struct DecoderBlock {
  LayerNorm norm1, norm2, norm3, norm_y;
  Attention attn;
  CrossAttention cross_attn;
  Mlp mlp;

  DecoderBlock() = default;
  DecoderBlock(int64_t dim, int64_t num_heads, int64_t mlp_ratio, double eps)
      : norm1(dim, eps), norm2(dim, eps), norm3(dim, eps), norm_y(dim, eps), attn(dim, num_heads),
        cross_attn(dim, num_heads), mlp(dim, dim * mlp_ratio) {}
  void registerIn(ParameterTable& table, const std::string& prefix);
  at::Tensor forward(const at::Tensor& x, const at::Tensor& y, const RopeFactors& x_rope,
                     const RopeFactors& y_rope) const;
};

}  // namespace ffloc::nn
