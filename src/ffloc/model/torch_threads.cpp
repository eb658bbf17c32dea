#include "ffloc/model/torch_threads.h"

#include <ATen/Parallel.h>
#include <omp.h>

#include <chrono>
#include <condition_variable>
#include <mutex>

#include "ffloc/core/progress.h"
#include "ffloc/core/threads.h"
#include "ffloc/model/cpu_gemm.h"

#ifndef _OPENMP
#error "torch_threads.cpp must be compiled with OpenMP (see parallelFor in torch_threads.h)"
#endif

namespace ffloc {
namespace {

// libtorch's count under OpenMP is each thread's own (OpenMP's nthreads ICV), read by
// at::parallel_for on that thread. at::set_num_threads also sets the default of later threads and
// rebuilds libtorch's pthreadpool, a process-wide change; this changes the calling thread only.
void setTorchThreadsOfThisThread(int threads) {
  // A thread's first call takes libtorch's default, which would otherwise overwrite ours later.
  if (at::get_num_threads() != threads) omp_set_num_threads(threads);
}

}  // namespace

int setTorchThreadCount(int requested) {
  // OpenBLAS backs libblas, and so libtorch's fp32 matmul, with a pool at::set_num_threads does
  // not reach: left alone it runs every core and spins in sched_yield when they are busy
  // (measured: a fifth of a training run's CPU time).
  const int threads = setLibraryThreadCount(requested);
  at::set_num_threads(threads);
  return threads;
}

int torchThreadCount() { return at::get_num_threads(); }

SingleThreadedKernels::SingleThreadedKernels()
    : blas_(std::make_unique<SingleThreadedBlas>()), saved_torch_threads_(at::get_num_threads()) {
  setTorchThreadsOfThisThread(1);
}

SingleThreadedKernels::~SingleThreadedKernels() { setTorchThreadsOfThisThread(saved_torch_threads_); }

namespace {

struct ThreadCountLeases {
  std::mutex mutex;
  std::condition_variable released;
  int threads = 0;  // the pools' count since the first lease with one; 0 before
  int holders = 0;
  int waiting_to_resize = 0;
};

ThreadCountLeases& threadCountLeases() {
  static ThreadCountLeases leases;
  return leases;
}

thread_local int leases_held_on_this_thread = 0;

}  // namespace

ThreadCountLease::ThreadCountLease(std::optional<int> requested) {
  const int threads = requested ? resolveThreadCount(*requested) : 0;
  ThreadCountLeases& leases = threadCountLeases();
  std::unique_lock<std::mutex> lock(leases.mutex);
  if (leases_held_on_this_thread > 0) {
    // Nested (a Python signal handler run by a call's check for Ctrl-C calls the library again):
    // waiting would wait for this thread's own lease, so it runs at the count held.
    ++leases.holders;
    ++leases_held_on_this_thread;
    return;
  }
  // Waits a tenth of a second at a time, asking this thread's StopCheck between: Ctrl-C in Python
  // ended a wait behind another thread's long build only when that build did.
  const auto waitUntil = [&](const auto& ready) {
    while (!leases.released.wait_for(lock, std::chrono::milliseconds(100), ready)) {
      lock.unlock();
      stopIfRequested("waiting for the thread pools held by another thread");
      lock.lock();
    }
  };
  for (;;) {
    if (requested && threads != leases.threads) {
      ++leases.waiting_to_resize;
      try {
        waitUntil([&] { return leases.holders == 0 || threads == leases.threads; });
      } catch (...) {
        lock.lock();
        --leases.waiting_to_resize;
        lock.unlock();
        leases.released.notify_all();
        throw;
      }
      --leases.waiting_to_resize;
      if (threads != leases.threads) {
        setTorchThreadCount(threads);
        leases.threads = threads;
      }
      leases.released.notify_all();
      break;
    }
    // Leases wait behind one that waits to resize: a stream of them would keep it waiting for ever.
    if (leases.waiting_to_resize == 0) break;
    waitUntil([&] { return leases.waiting_to_resize == 0 || (requested && threads != leases.threads); });
  }
  ++leases.holders;
  ++leases_held_on_this_thread;
  lock.unlock();
  if (requested) setTorchThreadsOfThisThread(threads);
}

ThreadCountLease::~ThreadCountLease() {
  ThreadCountLeases& leases = threadCountLeases();
  {
    const std::lock_guard<std::mutex> lock(leases.mutex);
    --leases.holders;
    --leases_held_on_this_thread;
  }
  leases.released.notify_all();
}

void parallelFor(int64_t begin, int64_t end, int64_t grain_size, const std::function<void(int64_t, int64_t)>& body) {
  at::parallel_for(begin, end, grain_size, body);
}

}  // namespace ffloc
