#pragma once

#include <ATen/core/Tensor.h>

#include <functional>

namespace ffloc {

// The DPT heads' stride-1 convolutions (3x3 with padding 1, and 1x1) in float32 on the CPU,
// as products on libtorch's intra-op threads with single-threaded OpenBLAS sgemm (cpu_gemm.h).
// A 3x3 convolution of a channels-last image is, per output row, nine products (tap rows x
// C_in) by (C_in x C_out) that accumulate into the row: no padding copy, no im2col buffer.
// On the 2-core Zen 3 machine this ran 1.1-2.5x faster than libtorch 1.13's own channels-last
// convolution for the heads' shapes (docs/benchmarks.md).

// Whether cpuConvolution serves this convolution: float32 CPU, no autograd, stride 1, and
// either 3x3 with padding 1 or 1x1 without padding.
bool cpuConvolutionApplies(const at::Tensor& x, const at::Tensor& weight, int64_t stride, int64_t padding);

// x (B, C_in, H, W) in any memory format, weight (C_out, C_in, k, k), bias (C_out) or undefined.
// Returns (B, C_out, H, W) in channels-last memory.
at::Tensor cpuConvolution(const at::Tensor& x, const at::Tensor& weight, const at::Tensor& bias);

// The (3, 3, C_in, C_out) tap matrices that conv3x3RowsOnThisThread reads, from a float32
// (C_out, C_in, 3, 3) weight.
at::Tensor convolutionTaps(const at::Tensor& weight);

// Output rows [first, last) of one image's 3x3 padding-1 convolution on the calling thread,
// into dst ((last - first) x cols x C_out floats, row-major pixels, channels last). source(r)
// returns input row r (cols x C_in floats) for the rows in [first - 1, last + 1) inside the
// image: the caller may produce them on the fly (the DPT output head upsamples them band by
// band). bias: C_out floats or null.
void conv3x3RowsOnThisThread(const std::function<const float*(int64_t)>& source, int64_t rows, int64_t cols, int64_t in, int64_t out,
                             const float* taps, const float* bias, float* dst, int64_t first, int64_t last);

}  // namespace ffloc
