#pragma once

#include <cstdint>
#include <string>

namespace ffloc {

// The most worker threads any entry point takes. Past 65536 TBB (OpenCV's pool) crashed, and long
// before that the pools' start-up and hand-offs swamped the work: a fastforward map of one image
// took 1.4 s with 2 threads, 33 s with 1000. 0 (all hardware threads) reaches every core of a
// larger machine.
inline constexpr int kMaxThreads = 256;

// What is wrong with asking for `requested` threads ("must be 0 (all hardware threads) to 256, got
// 300"), or "": one wording for resolveThreadCount, every --threads flag and training configs.
std::string threadCountProblem(int64_t requested);

// Number of worker threads to use when the user asked for `requested` (0 = all hardware threads).
// InputError naming `threads` outside [0, kMaxThreads].
int resolveThreadCount(int requested);

// Sets the thread pools of OpenBLAS (behind libblas: matrix products) and OpenCV (SIFT, image
// resampling; at most one thread per core) to resolveThreadCount(requested) and returns it. Left
// alone each starts one thread per core, and their pools and libtorch's then fight over the same
// cores. A pool already at its count is left alone. Resizing OpenCV's pool while another thread runs
// a loop in it crashes: a program computing on several threads sets the count before it starts
// them, or holds a ThreadCountLease (model/torch_threads.h) on each.
int setLibraryThreadCount(int requested);

// OpenBLAS's own pool, reached through the symbols libblas exports when it is OpenBLAS (Debian's
// libopenblas0-pthread): its thread count, 0 under another BLAS.
int blasThreadCount();
// Sets OpenBLAS's thread count; under another BLAS does nothing.
void setBlasThreadCount(int threads);
// "OpenBLAS, core <the kernel family it picked for this CPU>", or "not OpenBLAS".
std::string blasDescription();

}  // namespace ffloc
