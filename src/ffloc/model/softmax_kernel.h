#pragma once

#include <ATen/core/Tensor.h>

namespace ffloc {

// Softmax over the last dimension, written over `scores` (a contiguous float32 or bfloat16 CPU
// tensor without autograd history). On CPUs with AVX-512 (F, BW, VL) rows are processed with a
// vectorised exp in float32; elsewhere this is ATen's softmax. libtorch 1.13's own kernel spends
// ~2 ns per score on the Intel development machine, about as long as the attention matrix products themselves
// (profile in docs/benchmarks.md).
void softmaxLastDimInPlace(at::Tensor& scores);

// Whether softmaxLastDimInPlace uses its AVX-512 kernel on this CPU.
bool vectorizedSoftmaxAvailable();

}  // namespace ffloc
