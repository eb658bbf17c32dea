#pragma once

#ifdef FFLOC_WITH_TORCH

#include <cstdint>
#include <string>
#include <vector>

#include "bench_report.h"

namespace ffloc::cli {

// The options of `ffloc bench model` (bench_command.cpp registers them).
struct BenchModelArguments {
  std::string config = "large";
  std::vector<std::string> dtypes = {"fp32", "bf16"};
  int threads = 0;
  int repeats = 5;
  int warmup = 1;
  std::vector<int64_t> map_tokens = {1500, 3000};
  int64_t width = 512, height = 384;
  std::string reference;
  uint64_t seed = 0;
  bool profile = false;  // one more call per row with the per-kind profile
  bool json = false;     // JSON lines instead of the table
};

// Encoder on one image and DUSt3R's decoder + both DPT heads (with post-processing) on a pair:
// the two measurements of the Python reference.
void benchDust3r(const BenchModelArguments& args, const BenchReport& report, const std::string& dtype_name);

// FastForwardModel::forward for one query against each N of args.map_tokens: ray MLP, decoder,
// query DPT head (with post-processing) and map head.
void benchFastForward(const BenchModelArguments& args, const BenchReport& report, const std::string& dtype_name);

}  // namespace ffloc::cli

#endif  // FFLOC_WITH_TORCH
