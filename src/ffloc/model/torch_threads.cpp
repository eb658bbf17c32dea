#include "ffloc/model/torch_threads.h"

#include <ATen/Parallel.h>

#include "ffloc/core/threads.h"


namespace ffloc {

int setTorchThreadCount(int requested) {
  // OpenBLAS backs libblas, and so libtorch's fp32 matmul, with a pool at::set_num_threads does
  // not reach: left alone it runs every core and spins in sched_yield when they are busy
  // (measured: a fifth of a training run's CPU time).
  const int threads = setLibraryThreadCount(requested);
  at::set_num_threads(threads);
  return threads;
}

}  // namespace ffloc
