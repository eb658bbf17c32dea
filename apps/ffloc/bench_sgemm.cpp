#include "bench_sgemm.h"

#ifdef FFLOC_WITH_TORCH

#include <ATen/ops/mm.h>
#include <ATen/ops/rand.h>

#include "bench_measurement.h"

namespace ffloc::cli {

double measureSgemmGflops(int repeats) {
  const at::Tensor a = at::rand({kSgemmM, kSgemmK});
  const at::Tensor b = at::rand({kSgemmK, kSgemmN});
  at::Tensor c = at::mm(a, b);
  const Timing timing = timeCalls(1, repeats, [&] { at::mm_out(c, a, b); });
  return 2.0 * kSgemmM * kSgemmK * kSgemmN * 1e-9 / timing.median();
}

}  // namespace ffloc::cli

#endif  // FFLOC_WITH_TORCH
