#include "ffloc/core/threads.h"

#include <algorithm>
#include <opencv2/core/utility.hpp>
#include <thread>

// Weak, so builds against another BLAS still link and simply skip the call.
extern "C" void openblas_set_num_threads(int threads) __attribute__((weak));

namespace ffloc {

int resolveThreadCount(int requested) {
  if (requested > 0) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

int setLibraryThreadCount(int requested) {
  const int threads = resolveThreadCount(requested);
  if (openblas_set_num_threads != nullptr) openblas_set_num_threads(threads);
  cv::setNumThreads(threads);
  return threads;
}

}  // namespace ffloc
