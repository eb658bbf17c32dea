#pragma once

namespace ffloc::cli {

// The machine's fp32 GEMM rate in GFLOP/s as the network's Linear layers get it: a
// 3072x1024 by 1024x4096 product through libtorch (OpenBLAS sgemm here) at the thread count
// already set, median of `repeats` calls after one warm-up. `ffloc bench model` reports each
// row's rate as a share of it.
double measureSgemmGflops(int repeats);

// The product's shape, for the report.
constexpr int kSgemmM = 3072, kSgemmK = 1024, kSgemmN = 4096;

}  // namespace ffloc::cli
