#include "ffloc/model/layers.h"

#include <ATen/TensorOperators.h>
#include <ATen/core/grad_mode.h>
#include <ATen/ops/conv2d.h>
#include <ATen/ops/conv_transpose2d.h>
#include <ATen/ops/gelu.h>
#include <ATen/ops/layer_norm.h>
#include <ATen/ops/linear.h>
#include <ATen/ops/matmul.h>

#include "ffloc/model/bfloat16_kernels.h"
#include "ffloc/model/cpu_attention.h"
#include "ffloc/model/cpu_conv.h"
#include "ffloc/model/cpu_gemm.h"
#include "ffloc/model/op_profile.h"
#include "ffloc/model/torch_compat.h"

namespace ffloc::nn {

void Linear::registerIn(ParameterTable& table, const std::string& prefix) {
  table.add(prefix + ".weight", {out, in}, &weight);
  table.add(prefix + ".bias", {out}, &bias);
}

Linear Linear::withFloat32Weights() const {
  Linear wide = *this;
  wide.weight = widened(weight);
  wide.bias = widened(bias);
  return wide;
}

at::Tensor Linear::forward(const at::Tensor& x, const at::Tensor& residual) const {
  if (computesInFloat32(x)) {
    return narrowed(withFloat32Weights().forward(widened(x), widened(residual)), x.scalar_type());
  }
  const OpScope scope(OpKind::kGemm, 2.0 * static_cast<double>(x.numel()) * static_cast<double>(out));
  if (cpuGemmApplies(x, weight)) return cpuLinear(x, weight, bias, residual);
  at::Tensor y = at::linear(x, weight, bias);
  return residual.defined() ? residual + y : y;
}

void LayerNorm::registerIn(ParameterTable& table, const std::string& prefix) {
  table.add(prefix + ".weight", {dim}, &weight);
  table.add(prefix + ".bias", {dim}, &bias);
}

at::Tensor LayerNorm::forward(const at::Tensor& x) const {
  const OpScope scope(OpKind::kLayerNorm);
  if (x.scalar_type() == at::kFloat) return at::layer_norm(x, {dim}, weight, bias, eps);
  // libtorch 1.13's bf16 layer_norm on the CPU is ~7x slower than fp32 (38 ms against 5 ms for
  // 768x1024, measured); normalising in fp32 and casting back is faster and more accurate.
  return at::layer_norm(x.to(at::kFloat), {dim}, weight.to(at::kFloat), bias.to(at::kFloat), eps)
      .to(x.scalar_type());
}

void Conv2d::registerIn(ParameterTable& table, const std::string& prefix) {
  // ConvTranspose2d stores its weight as (in, out, k, k).
  if (transposed) {
    table.add(prefix + ".weight", {in, out, kernel, kernel}, &weight);
  } else {
    table.add(prefix + ".weight", {out, in, kernel, kernel}, &weight);
  }
  if (has_bias) table.add(prefix + ".bias", {out}, &bias);
}

namespace {

// A transposed convolution whose stride equals its kernel and without padding puts one k x k
// block per input pixel: a matrix product, then a pixel shuffle. libtorch 1.13's own
// conv_transpose2d routes bfloat16 to oneDNN's forward convolution and returns wrong shapes, and
// refuses inputs smaller than the kernel in any dtype; this form is exact in every dtype.
at::Tensor blockTransposedConv(const at::Tensor& x, const at::Tensor& weight, const at::Tensor& bias,
                               int64_t kernel) {
  const int64_t batch = x.size(0), in = x.size(1), rows = x.size(2), cols = x.size(3);
  const int64_t out = weight.size(1);
  // (B, C, H, W) x (C, O*k*k) -> (B, H, W, O, k, k) -> (B, H, k, W, k, O), a channels-last image.
  const at::Tensor pixels = x.permute({0, 2, 3, 1});
  const at::Tensor matrix = weight.reshape({in, out * kernel * kernel});
  // The threaded product wants the (out*k*k, in) layout: a copy of a small weight per call.
  at::Tensor blocks = cpuGemmApplies(pixels, matrix) ? cpuLinear(pixels, matrix.t().contiguous(), {}, {})
                                                     : at::matmul(pixels, matrix);
  blocks = blocks.reshape({batch, rows, cols, out, kernel, kernel}).permute({0, 1, 4, 2, 5, 3});
  at::Tensor image = blocks.reshape({batch, rows * kernel, cols * kernel, out}).permute({0, 3, 1, 2});
  if (bias.defined()) image = image + bias.reshape({1, out, 1, 1});
  return image;
}

// Multiply-adds x 2 of one call on x: per output pixel (input pixel when transposed) in x out x k^2.
double convolutionFlops(const at::Tensor& x, const Conv2d& conv) {
  const int64_t rows = conv.transposed ? x.size(2) : (x.size(2) + 2 * conv.padding - conv.kernel) / conv.stride + 1;
  const int64_t cols = conv.transposed ? x.size(3) : (x.size(3) + 2 * conv.padding - conv.kernel) / conv.stride + 1;
  return 2.0 * static_cast<double>(x.size(0) * rows * cols * conv.in * conv.out * conv.kernel * conv.kernel);
}

}  // namespace

Conv2d Conv2d::withFloat32Weights() const {
  Conv2d wide = *this;
  wide.weight = widened(weight);
  wide.bias = widened(bias);
  return wide;
}

at::Tensor Conv2d::forward(const at::Tensor& x) const {
  if (computesInFloat32(x)) return narrowed(withFloat32Weights().forward(widened(x)), x.scalar_type());
  const OpScope scope(OpKind::kConvolution, convolutionFlops(x, *this));
  if (transposed && stride == kernel && padding == 0) return blockTransposedConv(x, weight, bias, kernel);
  if (transposed) return at::conv_transpose2d(x, weight, bias, {stride, stride}, {padding, padding});
  if (cpuConvolutionApplies(x, weight, stride, padding)) return cpuConvolution(x, weight, bias);
  return at::conv2d(x, weight, bias, {stride, stride}, {padding, padding});
}

void Mlp::registerIn(ParameterTable& table, const std::string& prefix) {
  fc1.registerIn(table, prefix + ".fc1");
  fc2.registerIn(table, prefix + ".fc2");
}

at::Tensor Mlp::forward(const at::Tensor& x, const at::Tensor& residual) const {
  if (computesInFloat32(x)) {
    Mlp wide = *this;
    wide.fc1 = fc1.withFloat32Weights();
    wide.fc2 = fc2.withFloat32Weights();
    return narrowed(wide.forward(widened(x), widened(residual)), x.scalar_type());
  }
  at::Tensor hidden = fc1.forward(x);
  {
    const OpScope scope(OpKind::kGelu);
    // fc1's output is ours alone: without autograd GELU overwrites it (no 4C-wide allocation).
    if (at::GradMode::is_enabled() && hidden.requires_grad()) {
      hidden = at::gelu(hidden);
    } else {
      at::gelu_(hidden);
    }
  }
  return fc2.forward(hidden, residual);
}

namespace {

RopeFactors widenedRope(const RopeFactors& rope) { return {widened(rope.cos), widened(rope.signed_sin)}; }

// (B, N, C) -> (B, heads, N, C / heads).
at::Tensor splitHeads(const at::Tensor& x, int64_t num_heads) {
  return x.reshape({x.size(0), x.size(1), num_heads, x.size(2) / num_heads}).permute({0, 2, 1, 3});
}

// (B, heads, N, hd) -> (B, N, heads * hd).
at::Tensor mergeHeads(const at::Tensor& x) {
  const OpScope scope(OpKind::kLayout);
  return x.transpose(1, 2).reshape({x.size(0), x.size(2), x.size(1) * x.size(3)});
}

}  // namespace

void Attention::registerIn(ParameterTable& table, const std::string& prefix) {
  qkv.registerIn(table, prefix + ".qkv");
  proj.registerIn(table, prefix + ".proj");
}

at::Tensor Attention::forward(const at::Tensor& x, const RopeFactors& rope, const at::Tensor& residual) const {
  if (computesInFloat32(x)) {
    Attention wide = *this;
    wide.qkv = qkv.withFloat32Weights();
    wide.proj = proj.withFloat32Weights();
    return narrowed(wide.forward(widened(x), widenedRope(rope), widened(residual)), x.scalar_type());
  }
  const int64_t batch = x.size(0), tokens = x.size(1), dim = x.size(2);
  const at::Tensor fused = qkv.forward(x);  // (B, N, 3C): [q | k | v]
  const at::Tensor q_rows = fused.narrow(2, 0, dim), k_rows = fused.narrow(2, dim, dim);
  const at::Tensor v_rows = fused.narrow(2, 2 * dim, dim);
  if (ropeInPlaceApplies(q_rows, rope) && cpuAttentionApplies(q_rows, k_rows, v_rows)) {
    // q and k are rotated where the product wrote them and read from there by stride.
    applyRopeInPlace(q_rows, rope);
    applyRopeInPlace(k_rows, rope);
    at::Tensor merged;
    {
      const OpScope scope(OpKind::kAttention, 4.0 * static_cast<double>(batch * tokens * tokens * dim));
      merged = cpuAttention(q_rows, k_rows, v_rows, num_heads);
    }
    return proj.forward(merged, residual);
  }
  // (B, N, 3 * C) -> (3, B, heads, N, hd): the output channels are [q | k | v].
  const at::Tensor parts = fused.reshape({batch, tokens, 3, num_heads, dim / num_heads}).permute({2, 0, 3, 1, 4});
  const at::Tensor q = applyRope(parts[0], rope);
  const at::Tensor k = applyRope(parts[1], rope);
  return proj.forward(mergeHeads(torch_compat::attention(q, k, parts[2])), residual);
}

void CrossAttention::registerIn(ParameterTable& table, const std::string& prefix) {
  projq.registerIn(table, prefix + ".projq");
  projk.registerIn(table, prefix + ".projk");
  projv.registerIn(table, prefix + ".projv");
  proj.registerIn(table, prefix + ".proj");
}

at::Tensor CrossAttention::forward(const at::Tensor& query, const at::Tensor& key_value,
                                   const RopeFactors& query_rope, const RopeFactors& key_rope,
                                   const at::Tensor& residual) const {
  if (computesInFloat32(query)) {
    CrossAttention wide = *this;
    wide.projq = projq.withFloat32Weights();
    wide.projk = projk.withFloat32Weights();
    wide.projv = projv.withFloat32Weights();
    wide.proj = proj.withFloat32Weights();
    return narrowed(wide.forward(widened(query), widened(key_value), widenedRope(query_rope), widenedRope(key_rope),
                                 widened(residual)),
                    query.scalar_type());
  }
  const at::Tensor q_rows = projq.forward(query);
  const at::Tensor k_rows = projk.forward(key_value);
  const at::Tensor v_rows = projv.forward(key_value);
  if (ropeInPlaceApplies(q_rows, query_rope) && ropeInPlaceApplies(k_rows, key_rope) &&
      cpuAttentionApplies(q_rows, k_rows, v_rows)) {
    applyRopeInPlace(q_rows, query_rope);
    applyRopeInPlace(k_rows, key_rope);
    at::Tensor merged;
    {
      const OpScope scope(OpKind::kAttention,
                          4.0 * static_cast<double>(q_rows.size(0) * q_rows.size(1) * k_rows.size(1) * q_rows.size(2)));
      merged = cpuAttention(q_rows, k_rows, v_rows, num_heads);
    }
    return proj.forward(merged, residual);
  }
  const at::Tensor q = applyRope(splitHeads(q_rows, num_heads), query_rope);
  const at::Tensor k = applyRope(splitHeads(k_rows, num_heads), key_rope);
  const at::Tensor v = splitHeads(v_rows, num_heads);
  return proj.forward(mergeHeads(torch_compat::attention(q, k, v)), residual);
}

void EncoderBlock::registerIn(ParameterTable& table, const std::string& prefix) {
  norm1.registerIn(table, prefix + ".norm1");
  attn.registerIn(table, prefix + ".attn");
  norm2.registerIn(table, prefix + ".norm2");
  mlp.registerIn(table, prefix + ".mlp");
}

at::Tensor EncoderBlock::forward(const at::Tensor& x, const RopeFactors& rope) const {
  const at::Tensor h = attn.forward(norm1.forward(x), rope, x);
  return mlp.forward(norm2.forward(h), h);
}

void DecoderBlock::registerIn(ParameterTable& table, const std::string& prefix) {
  // state_dict order of the reference module.
  norm1.registerIn(table, prefix + ".norm1");
  attn.registerIn(table, prefix + ".attn");
  cross_attn.registerIn(table, prefix + ".cross_attn");
  norm2.registerIn(table, prefix + ".norm2");
  norm3.registerIn(table, prefix + ".norm3");
  mlp.registerIn(table, prefix + ".mlp");
  norm_y.registerIn(table, prefix + ".norm_y");
}

at::Tensor DecoderBlock::forward(const at::Tensor& x, const at::Tensor& y, const RopeFactors& x_rope,
                                 const RopeFactors& y_rope) const {
  const at::Tensor h1 = attn.forward(norm1.forward(x), x_rope, x);
  const at::Tensor y_normed = norm_y.forward(y);
  const at::Tensor h2 = cross_attn.forward(norm2.forward(h1), y_normed, x_rope, y_rope, h1);
  return mlp.forward(norm3.forward(h2), h2);
}

}  // namespace ffloc::nn
