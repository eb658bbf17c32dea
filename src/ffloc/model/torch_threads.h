#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>

namespace ffloc {

class SingleThreadedBlas;

// Sets libtorch's intra-op thread count to resolveThreadCount(requested) (0 = all hardware
// threads), for the calling thread and as the default of threads started later, together with
// OpenBLAS's and OpenCV's pools (setLibraryThreadCount), and returns it. libtorch has been seen to
// start with a single thread, so callers set this explicitly before running the network. The
// pools are the process's: a program that computes on several threads sets them before it starts
// them, or holds a ThreadCountLease on each.
int setTorchThreadCount(int requested);
// libtorch's intra-op thread count on the calling thread.
int torchThreadCount();

// For its lifetime, libtorch's kernels called from this thread run on it alone, and so does
// OpenBLAS (SingleThreadedBlas, for every thread while any holder lives): for callers that run
// independent items on threads of their own (one frame per thread, two network passes side by
// side), each of which holds one. OpenCV's pool is left as it is: loops from several threads share
// it, and resizing it while another thread runs a loop in it crashed the process.
class SingleThreadedKernels {
 public:
  SingleThreadedKernels();
  ~SingleThreadedKernels();
  SingleThreadedKernels(const SingleThreadedKernels&) = delete;
  SingleThreadedKernels& operator=(const SingleThreadedKernels&) = delete;

 private:
  std::unique_ptr<SingleThreadedBlas> blas_;
  int saved_torch_threads_;
};

// Holds the pools of setTorchThreadCount at resolveThreadCount(requested) threads while alive, for
// programs whose threads each choose a count (the Python module's `threads=`). Leases of the
// pools' current count are held side by side; a lease of another count waits until none is held,
// then resizes the pools. Resizing OpenCV's pool while another thread ran a loop in it crashed the
// process, or left that loop waiting forever. Without a count (nullopt) a lease keeps the pools as
// they are, for work that runs OpenCV's loops but chose no count (reading an image). A lease
// nested in one its thread holds runs at the count held, whatever it asks. A wait asks the
// thread's StopCheck (core/progress.h) ten times a second, and ends with Stopped when told.
class ThreadCountLease {
 public:
  explicit ThreadCountLease(std::optional<int> requested);
  ~ThreadCountLease();
  ThreadCountLease(const ThreadCountLease&) = delete;
  ThreadCountLease& operator=(const ThreadCountLease&) = delete;
};

// at::parallel_for on libtorch's intra-op threads, for the network's own kernels. It exists
// because at::parallel_for is a template whose '#pragma omp parallel' expands in the caller's
// translation unit: in one compiled without OpenMP it runs every chunk on the calling thread,
// silently (measured: the large encoder took 6.9 s with 2 threads and with 1). This file is
// compiled with OpenMP, the runtime libtorch itself uses.
void parallelFor(int64_t begin, int64_t end, int64_t grain_size, const std::function<void(int64_t, int64_t)>& body);

}  // namespace ffloc
