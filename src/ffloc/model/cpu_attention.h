#pragma once

#include <ATen/core/Tensor.h>

namespace ffloc {

// Multi-head attention softmax(q k^T * head_dim^-0.5) v for float32 CPU tensors without
// autograd, in the layout the projections produce: q (B, Nq, C), k and v (B, Nk, C), each
// possibly a column range of a wider product (the [q | k | v] output of a qkv Linear), head h
// owning channels [h * hd, (h + 1) * hd). Returns (B, Nq, C) contiguous with the heads in
// order, i.e. already merged: the head split and merge are strides, not copies.
//
// Work is one task per (batch, head, block of queries), spread over libtorch's intra-op
// threads: a block's scores (block x Nk) stay in the core's L2 cache between q k^T, the
// softmax and the product with v, instead of a (heads, Nq, Nk) tensor going through memory three
// times. The scale multiplies the scores, as the reference does.
at::Tensor cpuAttention(const at::Tensor& q, const at::Tensor& k, const at::Tensor& v, int64_t num_heads);

// Whether cpuAttention serves these inputs.
bool cpuAttentionApplies(const at::Tensor& q, const at::Tensor& k, const at::Tensor& v);

}  // namespace ffloc
