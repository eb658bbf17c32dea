#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

namespace ffloc {

// float32 matrix products of the network on the CPU with one thread pool: the work is split over
// libtorch's intra-op threads and each piece is one single-threaded OpenBLAS sgemm. Left to
// itself OpenBLAS runs its own pool beside libtorch's OpenMP one, and on two cores the two
// pools' spinning workers take turns on the cores (docs/benchmarks.md, "Threads").

// Whether these kernels serve a product of x with a weight: float32 CPU tensors, no autograd.
bool cpuGemmApplies(const at::Tensor& x, const at::Tensor& weight);

// residual + x weight^T + bias, x (..., in), weight (out, in); bias and residual may be
// undefined. The output is a new contiguous (..., out) tensor.
at::Tensor cpuLinear(const at::Tensor& x, const at::Tensor& weight, const at::Tensor& bias,
                     const at::Tensor& residual);

// C = alpha A B^T (b_transposed) or alpha A B, plus beta C, row-major, on the calling thread
// only: for callers that parallelise themselves (attention, blockwise products).
void sgemmOnThisThread(bool b_transposed, int64_t m, int64_t n, int64_t k, float alpha, const float* a,
                       int64_t lda, const float* b, int64_t ldb, float beta, float* c, int64_t ldc);

// Holds OpenBLAS at one thread while alive (nesting and concurrent holders allowed; the count
// the process had is restored when the last one ends), so that sgemm called from several intra-op
// threads at once runs on each caller alone.
class SingleThreadedBlas {
 public:
  SingleThreadedBlas();
  ~SingleThreadedBlas();
  SingleThreadedBlas(const SingleThreadedBlas&) = delete;
  SingleThreadedBlas& operator=(const SingleThreadedBlas&) = delete;
};

}  // namespace ffloc
