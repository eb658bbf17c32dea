#include "ffloc/model/torch_threads.h"

#include <ATen/Parallel.h>

#include "ffloc/core/threads.h"

// OpenBLAS (which backs libblas, and so libtorch's fp32 matmul) keeps its own thread pool that
// at::set_num_threads does not reach: left alone it runs every core and spins in sched_yield when
// they are busy (measured: a fifth of a training run's CPU time). Weak, so builds against another
// BLAS still link and simply skip the call.
extern "C" void openblas_set_num_threads(int threads) __attribute__((weak));

namespace ffloc {

int setTorchThreadCount(int requested) {
  const int threads = resolveThreadCount(requested);
  at::set_num_threads(threads);
  if (openblas_set_num_threads != nullptr) openblas_set_num_threads(threads);
  return threads;
}

}  // namespace ffloc
