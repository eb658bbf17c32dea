#pragma once

#include <ATen/core/Tensor.h>

namespace ffloc {

// Softmax over the last dimension, written over `scores` (a contiguous float32 or bfloat16 CPU
// tensor without autograd history). On CPUs with AVX-512 (F, BW, VL) rows are processed with a
// vectorised exp in float32, and float32 rows likewise with AVX2 + FMA (AMD Zen 3); elsewhere
// this is ATen's softmax. libtorch 1.13's own kernel spends
// ~2 ns per score on the Intel development machine, about as long as the attention matrix products themselves
// (profile in docs/benchmarks.md).
void softmaxLastDimInPlace(at::Tensor& scores);

// `rows` contiguous float32 rows of `length` scores, in place, on the calling thread: for
// kernels that parallelise themselves (cpu_attention.h).
void softmaxRowsOnThisThread(float* data, int64_t rows, int64_t length);

// Whether softmaxLastDimInPlace uses its AVX-512 kernel on this CPU.
bool vectorizedSoftmaxAvailable();

}  // namespace ffloc
