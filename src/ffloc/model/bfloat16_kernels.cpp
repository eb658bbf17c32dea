#include "ffloc/model/bfloat16_kernels.h"

#include <ATen/core/grad_mode.h>

#include <atomic>

#include "ffloc/core/cpu_features.h"
#include "ffloc/model/op_profile.h"

namespace ffloc {

namespace {

std::atomic<Bfloat16Kernels>& chosenKernels() {
  static std::atomic<Bfloat16Kernels> kernels{Bfloat16Kernels::kAuto};
  return kernels;
}

}  // namespace

bool computesInFloat32(const at::Tensor& x) {
  if (!x.defined() || !x.is_cpu() || x.scalar_type() != at::kBFloat16) return false;
  if (at::GradMode::is_enabled() && x.requires_grad()) return false;
  switch (chosenKernels().load(std::memory_order_relaxed)) {
    case Bfloat16Kernels::kFloat32: return true;
    case Bfloat16Kernels::kLibtorch: return false;
    case Bfloat16Kernels::kAuto: break;
  }
  return !cpuHasNativeBfloat16();
}

at::Tensor widened(const at::Tensor& t) {
  if (!t.defined() || t.scalar_type() != at::kBFloat16) return t;
  const OpScope scope(OpKind::kLayout);
  return t.to(at::kFloat);
}

at::Tensor narrowed(const at::Tensor& t, at::ScalarType dtype) {
  if (t.scalar_type() == dtype) return t;
  const OpScope scope(OpKind::kLayout);
  return t.to(dtype);
}

ScopedBfloat16Kernels::ScopedBfloat16Kernels(Bfloat16Kernels kernels) : previous_(chosenKernels().exchange(kernels)) {}

ScopedBfloat16Kernels::~ScopedBfloat16Kernels() { chosenKernels().store(previous_); }

}  // namespace ffloc
