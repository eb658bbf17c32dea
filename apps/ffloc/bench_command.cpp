// `ffloc bench model`: the options, the header and the order of the rows. The rows are in
// bench_model_rows.cpp, what is printed in bench_report.cpp. Method and results:
// docs/benchmarks.md.
#ifdef FFLOC_WITH_TORCH

#include <ATen/Context.h>
#include <ATen/Parallel.h>
#include <torch/version.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>

#include "bench_measurement.h"
#include "bench_model_rows.h"
#include "bench_reference.h"
#include "bench_report.h"
#include "bench_sgemm.h"
#include "command_options.h"
#include "commands.h"
#include "ffloc/core/clock.h"
#include "ffloc/core/cpu_features.h"
#include "ffloc/core/error.h"
#include "ffloc/core/threads.h"
#include "ffloc/model/dust3r_model.h"
#include "ffloc/model/model_options.h"
#include "ffloc/model/torch_threads.h"

namespace ffloc::cli {
namespace {

// Upper bounds beyond any measurement worth making: --height 100000 took 2.5 GB and had not
// finished one call after 30 s, and a billion repeats never end.
constexpr int kMaxBenchSide = 4096;
constexpr int64_t kMaxBenchRepeats = 10000, kMaxBenchMapTokens = 1000000;

void validate(const BenchModelArguments& args) {
  if (args.repeats < 1 || args.repeats > kMaxBenchRepeats)
    throw InputError("--repeats: must be in [1, " + std::to_string(kMaxBenchRepeats) + "]");
  if (args.warmup < 0 || args.warmup > kMaxBenchRepeats)
    throw InputError("--warmup: must be in [0, " + std::to_string(kMaxBenchRepeats) + "]");
  if (args.dtypes.empty()) throw InputError("--dtype: give at least one of f32, bf16");
  // Two spellings of one precision (f32,fp32) timed it twice, as two rows.
  std::vector<at::ScalarType> precisions;
  for (const auto& dtype : args.dtypes) {
    const at::ScalarType precision = parseNetworkDtype(dtype, "--dtype");
    if (std::find(precisions.begin(), precisions.end(), precision) != precisions.end())
      throw InputError("--dtype: '" + dtype + "' names a precision given before");
    precisions.push_back(precision);
  }
  for (const int64_t count : args.map_tokens) {
    if (count < 1 || count > kMaxBenchMapTokens)
      throw InputError("--features: map token counts must be in [1, " + std::to_string(kMaxBenchMapTokens) + "], got " +
                       std::to_string(count));
  }
  Dust3rConfig config;
  try {
    config = Dust3rConfig::preset(args.config);
  } catch (const InputError& e) {
    throw InputError(std::string("--config: ") + e.what());
  }
  if (args.width <= 0 || args.height <= 0 || args.width % config.patch_size != 0 ||
      args.height % config.patch_size != 0 || args.width > kMaxBenchSide || args.height > kMaxBenchSide) {
    throw InputError("--width/--height: " + std::to_string(args.width) + "x" + std::to_string(args.height) +
                     " is not a positive multiple of the patch size " + std::to_string(config.patch_size) +
                     " of at most " + std::to_string(kMaxBenchSide));
  }
}

int64_t parameterCount(const std::string& preset) {
  Dust3rModel model(Dust3rConfig::preset(preset));
  const ParameterTable table = model.parameterTable();
  int64_t count = 0;
  for (const auto& entry : table.entries()) {
    int64_t numel = 1;
    for (const int64_t size : entry.shape) numel *= size;
    count += numel;
  }
  return count;
}

void printHeader(const BenchModelArguments& args, const BenchReport& report, const std::string& blas) {
  const Dust3rConfig config = Dust3rConfig::preset(args.config);
  const int64_t tokens = (args.width / config.patch_size) * (args.height / config.patch_size);
  std::printf("ffloc bench model: DUSt3R '%s' config (%.1f M parameters), %lldx%lld images (%lld tokens)\n",
              args.config.c_str(), parameterCount(args.config) * 1e-6, static_cast<long long>(args.width),
              static_cast<long long>(args.height), static_cast<long long>(tokens));
  std::printf("libtorch %s, %d intra-op threads; fp32 BLAS: %s; oneDNN %s; CPU amx_bf16 %s, avx512_bf16 %s\n",
              TORCH_VERSION, at::get_num_threads(), blas.c_str(), at::hasMKLDNN() ? "available" : "absent",
              cpuHasFlag("amx_bf16") ? "yes" : "no", cpuHasFlag("avx512_bf16") ? "yes" : "no");
  std::printf("%d warm-up + %d timed calls per row, median (min..max) in seconds; random weights; "
              "GFLOP counted analytically (docs/benchmarks.md)\n",
              args.warmup, args.repeats);
  if (report.comparable()) {
    std::printf("reference: %s (Python PyTorch eager, 2 threads; ffloc/Python = ffloc median / Python pooled median)\n",
                report.referencePath().c_str());
  } else if (report.hasReference()) {
    std::printf("reference: %s is for the large config at 512x384, so no ratios here\n",
                report.referencePath().c_str());
  } else {
    std::printf("reference: none (set FFLOC_SHARED_DIR or pass --reference for the Python ratios)\n");
  }
  std::printf("load average at start: %s\n", loadAverage().c_str());
}

void runBenchModel(const BenchModelArguments& args) {
  validate(args);
  const int threads = setTorchThreadCount(args.threads);
  // setTorchThreadCount set OpenBLAS's pool too (fp32 matmuls go to it): the header says which.
  const std::string blas = blasThreadCount() > 0
                               ? blasDescription() + ", " + std::to_string(blasThreadCount()) + " threads"
                               : "not OpenBLAS (thread count left as is)";
  BenchReport report({args.config, args.width, args.height, threads, args.json}, findReferenceTiming(args.reference));
  if (!args.json) printHeader(args, report, blas);
  const auto start = std::chrono::steady_clock::now();
  const double sgemm = measureSgemmGflops(5);
  report.sgemm(sgemm, secondsSince(start));
  if (!args.json) std::printf("\n");
  report.header();
  for (const auto& dtype : args.dtypes) {
    benchDust3r(args, report, dtype);
    if (!args.map_tokens.empty()) benchFastForward(args, report, dtype);
  }
  if (!args.json) std::printf("\nload average at end: %s\n", loadAverage().c_str());
}

}  // namespace

void registerBenchCommand(CLI::App& app, CommandRun& run) {
  CLI::App* bench = app.add_subcommand("bench", "Timings of the network on this machine");
  bench->require_subcommand(1);
  auto args = std::make_shared<BenchModelArguments>();
  CLI::App* cmd = bench->add_subcommand(
      "model", "Wall time, GFLOP/s and peak RSS of the encoder, the FastForward decoder + query head and "
               "DUSt3R's decoder + heads, with random weights, beside the Python reference timing");
  cmd->add_option("--config", args->config, "Network size: large (the official DUSt3R), small or tiny")
      ->capture_default_str();
  cmd->add_option("--dtype", args->dtypes, "Network precisions, comma-separated: fp32 (the reference timing's spelling; f32 elsewhere, taken here too), bf16 (bf16: encoder, decoder and DPT heads, as the reference under CPU autocast)")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "Intra-op and BLAS threads (0 = all hardware threads)")
      ->check(threadCountRange())
      ->capture_default_str();
  cmd->add_option("--repeats", args->repeats, "Timed calls per row (the median is reported)")
      ->capture_default_str();
  cmd->add_option("--warmup", args->warmup, "Untimed calls before each row")->capture_default_str();
  cmd->add_option("--features", args->map_tokens, "Map token counts N for FastForward, comma-separated")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--width", args->width, "Image width (pixels)")->capture_default_str();
  cmd->add_option("--height", args->height, "Image height (pixels)")->capture_default_str();
  cmd->add_option("--reference", args->reference,
                  "Python reference timing file (default: $FFLOC_SHARED_DIR/fixtures/dust3r/"
                  "python_reference_timing.txt when it exists)");
  cmd->add_option("--seed", args->seed, "Seed of the random weights and inputs")->check(wholeNumber())->capture_default_str();
  cmd->add_flag("--profile", args->profile,
                "After each row, one more call with the time and GFLOP/s per kind of operation (GEMM, attention, "
                "softmax, layer norm, GELU, RoPE, copies, convolutions)");
  cmd->add_flag("--json", args->json,
                "One JSON object per line instead of the table: each row with row, dtype, threads, median_s, gflop, "
                "sgemm_share; the sgemm rate, memory and profiles");
  cmd->callback([args, &run] {
    run = [args] {
      runBenchModel(*args);
      return 0;
    };
  });
}

}  // namespace ffloc::cli

#endif  // FFLOC_WITH_TORCH
