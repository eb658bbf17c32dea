#include "ffloc/core/threads.h"

#include <algorithm>
#include <opencv2/core/utility.hpp>
#include <thread>

#include "ffloc/core/error.h"

// Weak, so builds against another BLAS still link and simply skip the calls.
extern "C" void openblas_set_num_threads(int threads) __attribute__((weak));
extern "C" int openblas_get_num_threads(void) __attribute__((weak));
extern "C" char* openblas_get_corename(void) __attribute__((weak));

namespace ffloc {

std::string threadCountProblem(int64_t requested) {
  if (requested >= 0 && requested <= kMaxThreads) return "";
  return "must be 0 (all hardware threads) to " + std::to_string(kMaxThreads) + ", got " + std::to_string(requested);
}

int resolveThreadCount(int requested) {
  if (const std::string problem = threadCountProblem(requested); !problem.empty())
    throw InputError("threads: " + problem);
  if (requested > 0) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

int setLibraryThreadCount(int requested) {
  const int threads = resolveThreadCount(requested);
  if (blasThreadCount() != threads) setBlasThreadCount(threads);
  // TBB, OpenCV's pool, runs no more workers than the cores this process may use (its affinity
  // mask, not the machine's count), and says so on stderr when asked to. Set only when it changes:
  // OpenCV rebuilds the pool even for its own count, which crashed a loop another thread ran in it.
  const int opencv_threads = std::min(threads, cv::getNumberOfCPUs());
  if (cv::getNumThreads() != opencv_threads) cv::setNumThreads(opencv_threads);
  return threads;
}

int blasThreadCount() { return openblas_get_num_threads != nullptr ? openblas_get_num_threads() : 0; }

void setBlasThreadCount(int threads) {
  if (openblas_set_num_threads != nullptr) openblas_set_num_threads(threads);
}

std::string blasDescription() {
  if (openblas_set_num_threads == nullptr) return "not OpenBLAS";
  return std::string("OpenBLAS, core ") + (openblas_get_corename != nullptr ? openblas_get_corename() : "unknown");
}

}  // namespace ffloc
