#pragma once

// Which kernels compute the network's bfloat16 layers on the CPU. Where the CPU has native bf16
// (AMX or AVX512-BF16), libtorch's bf16 kernels (oneDNN). Elsewhere libtorch 1.13 emulates bf16
// products element by element (an encoder pass of the large model took 761 s against 3.3 s in
// float32 on Zen 3) and convolves through im2col buffers of hundreds of MB, so there each layer
// widens its bf16 input and weights to float32, runs the float32 kernels and rounds its output
// back to bf16: what is stored between layers (weights, activations) stays bf16, and the sums are
// float32, as oneDNN's bf16 products accumulate them.

#include <ATen/core/Tensor.h>

namespace ffloc {

enum class Bfloat16Kernels {
  kAuto,     // float32 where the CPU has no native bf16, libtorch's otherwise
  kFloat32,  // always widen (tests compare it with libtorch's on every CPU)
  kLibtorch  // never widen
};

// Whether a layer given `x` computes in float32 and rounds its output back: a bf16 CPU tensor, no
// autograd through it, and float32 kernels chosen for this CPU.
bool computesInFloat32(const at::Tensor& x);

// float32 copy of a bf16 tensor; other tensors (float32, undefined) as they are.
at::Tensor widened(const at::Tensor& t);

// `t` rounded to `dtype` where it is not already.
at::Tensor narrowed(const at::Tensor& t, at::ScalarType dtype);

// Chooses the kernels while alive (for tests and benchmarks), restoring the choice before it.
class ScopedBfloat16Kernels {
 public:
  explicit ScopedBfloat16Kernels(Bfloat16Kernels kernels);
  ~ScopedBfloat16Kernels();
  ScopedBfloat16Kernels(const ScopedBfloat16Kernels&) = delete;
  ScopedBfloat16Kernels& operator=(const ScopedBfloat16Kernels&) = delete;

 private:
  Bfloat16Kernels previous_;
};

}  // namespace ffloc
