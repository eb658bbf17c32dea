#pragma once

#include <cstdint>
#include <functional>

namespace ffloc {

// Sets libtorch's intra-op thread count to resolveThreadCount(requested) (0 = all hardware
// threads) and returns it. libtorch has been seen to start with a single thread, so callers set
// this explicitly before running the network.
int setTorchThreadCount(int requested);
int torchThreadCount();

// For its lifetime, libtorch's, OpenBLAS's and OpenCV's pools at one thread each, for callers
// that run independent items on threads of their own (one frame per thread). The counts are
// process-wide, so guards that overlap (two queries from two threads) share one saving: the
// first saves the counts, the last restores them.
class SingleThreadedKernels {
 public:
  SingleThreadedKernels();
  ~SingleThreadedKernels();
  SingleThreadedKernels(const SingleThreadedKernels&) = delete;
  SingleThreadedKernels& operator=(const SingleThreadedKernels&) = delete;
};

// at::parallel_for on libtorch's intra-op threads, for the network's own kernels. It exists
// because at::parallel_for is a template whose '#pragma omp parallel' expands in the caller's
// translation unit: in one compiled without OpenMP it runs every chunk on the calling thread,
// silently (measured: the large encoder took 6.9 s with 2 threads and with 1). This file is
// compiled with OpenMP, the runtime libtorch itself uses.
void parallelFor(int64_t begin, int64_t end, int64_t grain_size, const std::function<void(int64_t, int64_t)>& body);

}  // namespace ffloc
