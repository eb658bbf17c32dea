#include "ffloc/model/torch_threads.h"

#include <ATen/Parallel.h>

#include <mutex>

#include <opencv2/core/utility.hpp>

#include "ffloc/core/threads.h"

#ifndef _OPENMP
#error "torch_threads.cpp must be compiled with OpenMP (see parallelFor in torch_threads.h)"
#endif

namespace ffloc {

int setTorchThreadCount(int requested) {
  // OpenBLAS backs libblas, and so libtorch's fp32 matmul, with a pool at::set_num_threads does
  // not reach: left alone it runs every core and spins in sched_yield when they are busy
  // (measured: a fifth of a training run's CPU time).
  const int threads = setLibraryThreadCount(requested);
  at::set_num_threads(threads);
  return threads;
}

int torchThreadCount() { return at::get_num_threads(); }

namespace {

struct SavedThreadCounts {
  std::mutex mutex;
  int guards = 0;
  int torch = 1, blas = 0, opencv = 1;
};

SavedThreadCounts& savedThreadCounts() {
  static SavedThreadCounts saved;
  return saved;
}

}  // namespace

SingleThreadedKernels::SingleThreadedKernels() {
  SavedThreadCounts& saved = savedThreadCounts();
  const std::lock_guard<std::mutex> lock(saved.mutex);
  if (saved.guards++ > 0) return;
  saved.torch = at::get_num_threads();
  saved.blas = blasThreadCount();
  saved.opencv = cv::getNumThreads();
  at::set_num_threads(1);
  setBlasThreadCount(1);
  cv::setNumThreads(1);
}

SingleThreadedKernels::~SingleThreadedKernels() {
  SavedThreadCounts& saved = savedThreadCounts();
  const std::lock_guard<std::mutex> lock(saved.mutex);
  if (--saved.guards > 0) return;
  at::set_num_threads(saved.torch);
  if (saved.blas > 0) setBlasThreadCount(saved.blas);
  cv::setNumThreads(saved.opencv);
}

void parallelFor(int64_t begin, int64_t end, int64_t grain_size, const std::function<void(int64_t, int64_t)>& body) {
  at::parallel_for(begin, end, grain_size, body);
}

}  // namespace ffloc
