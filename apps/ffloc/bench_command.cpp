// `ffloc bench model`: CPU timings of the network with random weights, beside the Python
// reference timing of the same DUSt3R configuration. Method and results: docs/benchmarks.md.
#ifdef FFLOC_WITH_TORCH

#include <ATen/Context.h>
#include <ATen/Parallel.h>
#include <ATen/TensorOperators.h>
#include <ATen/ops/cat.h>
#include <ATen/ops/rand.h>
#include <ATen/ops/randn.h>
#include <torch/version.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bench_measurement.h"
#include "bench_reference.h"
#include "commands.h"
#include "ffloc/core/cpu_features.h"
#include "ffloc/core/error.h"
#include "ffloc/model/fastforward_model.h"
#include "ffloc/model/map_assembly.h"
#include "ffloc/model/model_loader.h"
#include "ffloc/model/model_options.h"
#include "ffloc/model/torch_threads.h"
#include "flop_count.h"

namespace ffloc::cli {
namespace {

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
};

// `count` map tokens assembled as localisation and training assemble them (map_assembly.h), from
// mapping cameras on a circle looking inwards and random encoder tokens.
MapTokens randomMapTokens(const Dust3rConfig& config, int64_t rows, int64_t cols, int64_t count,
                          at::ScalarType dtype, uint64_t seed) {
  const int64_t per_image = rows * cols;
  // At least a handful of images, as after retrieval, and enough to hold all N tokens.
  const int64_t images = std::max<int64_t>(8, (count + per_image - 1) / per_image);
  const int patch = static_cast<int>(config.patch_size);
  std::vector<MapCamera> cameras;
  std::vector<Dust3rEncoding> encodings;
  for (int64_t k = 0; k < images; ++k) {
    MapCamera camera;
    camera.intrinsics.width = static_cast<int>(cols) * patch;
    camera.intrinsics.height = static_cast<int>(rows) * patch;
    camera.intrinsics.fx = camera.intrinsics.fy = 0.8 * camera.intrinsics.width;
    camera.intrinsics.cx = 0.5 * (camera.intrinsics.width - 1);
    camera.intrinsics.cy = 0.5 * (camera.intrinsics.height - 1);
    const double angle = 2.0 * 3.141592653589793 * static_cast<double>(k) / static_cast<double>(images);
    camera.camera_to_world.R = Eigen::AngleAxisd(-angle, Eigen::Vector3d::UnitY()).toRotationMatrix();
    camera.camera_to_world.t = -2.0 * (camera.camera_to_world.R * Eigen::Vector3d::UnitZ());
    camera.name = "bench_" + std::to_string(k);
    cameras.push_back(camera);
    Dust3rEncoding encoding;
    encoding.tokens = at::randn({1, per_image, config.enc_dim}).to(dtype);
    encoding.positions = patchPositions(1, rows, cols, at::kCPU);
    encoding.height = rows * patch;
    encoding.width = cols * patch;
    encodings.push_back(encoding);
  }
  return assembleMapTokens(planMap(cameras, patch, count, seed), encodings);
}

class Report {
 public:
  Report(const BenchModelArguments& args, std::optional<ReferenceTiming> reference)
      : args_(args), reference_(std::move(reference)) {}

  void header() const {
    std::printf("%-5s %-40s %9s %17s %8s %8s   %-28s %s\n", "dtype", "what", "median s", "(min..max)", "GFLOP",
                "GFLOP/s", "Python s (runs; pooled)", "ffloc/Python");
    std::fflush(stdout);
  }

  void row(const std::string& dtype, const std::string& what, const Timing& timing, double flops,
           const std::map<std::string, ReferenceRow>* reference_rows) const {
    char range[64];
    std::snprintf(range, sizeof(range), "(%.3f..%.3f)", timing.min(), timing.max());
    std::printf("%-5s %-40s %9.3f %17s %8.1f %8.1f", dtype.c_str(), what.c_str(), timing.median(), range,
                flops * 1e-9, flops * 1e-9 / timing.median());
    const ReferenceRow* reference = reference_rows ? findRow(*reference_rows, dtype) : nullptr;
    if (reference) {
      std::string runs;
      if (!reference->process_medians.empty()) {
        const auto [low, high] =
            std::minmax_element(reference->process_medians.begin(), reference->process_medians.end());
        char text[48];
        std::snprintf(text, sizeof(text), "%.2f-%.2f", *low, *high);
        runs = text;
      }
      char pooled[32] = "";
      if (reference->pooled_median) std::snprintf(pooled, sizeof(pooled), "; %.2f", *reference->pooled_median);
      std::printf("   %-28s", (runs + pooled).c_str());
      std::optional<double> base = reference->pooled_median;
      if (!base && !reference->process_medians.empty()) base = Timing{reference->process_medians}.median();
      if (base) std::printf(" %.2f", timing.median() / *base);
    }
    std::printf("\n");
    std::fflush(stdout);
  }

  const std::map<std::string, ReferenceRow>* encoderReference() const { return comparable() ? &reference_->encoder : nullptr; }
  const std::map<std::string, ReferenceRow>* pairReference() const { return comparable() ? &reference_->pair : nullptr; }
  bool hasReference() const { return reference_.has_value(); }
  bool comparable() const {
    return reference_ && args_.config == kReferenceConfig && args_.width == kReferenceWidth &&
           args_.height == kReferenceHeight;
  }
  const std::filesystem::path& referencePath() const { return reference_->path; }

 private:
  static const ReferenceRow* findRow(const std::map<std::string, ReferenceRow>& rows, const std::string& dtype) {
    const auto it = rows.find(dtype);
    return it == rows.end() ? nullptr : &it->second;
  }

  const BenchModelArguments& args_;
  std::optional<ReferenceTiming> reference_;
};

void printMemory(const std::string& dtype, const std::string& model, const MemoryReport& memory) {
  std::printf("%-5s %-40s RSS after building %.0f MiB, peak while timing %.0f MiB%s\n", dtype.c_str(),
              (model + " memory").c_str(), memory.after_build_mib, memory.peak_mib,
              memory.peak_is_per_model ? "" : " (process-wide ru_maxrss)");
  std::fflush(stdout);
}

// Encoder on one image and DUSt3R's decoder + both DPT heads (with post-processing) on a pair:
// the two measurements of the Python reference.
void benchDust3r(const BenchModelArguments& args, const Report& report, const std::string& dtype_name) {
  const at::ScalarType dtype = parseNetworkDtype(dtype_name);
  at::manual_seed(args.seed);
  Dust3rModel model(Dust3rConfig::preset(args.config));
  randomizeParameters(model.parameterTable(), args.seed, dtype);
  model.to(at::kCPU, dtype, dtype);
  MemoryReport memory = startMemoryWindow();
  const Dust3rConfig& config = model.config();
  const at::Tensor image1 = at::rand({1, 3, args.height, args.width}) * 2 - 1;
  const at::Tensor image2 = at::rand({1, 3, args.height, args.width}) * 2 - 1;

  const Timing encoder = timeCalls(args.warmup, args.repeats, [&] { model.encode(image1); });
  report.row(dtype_name, "encoder, 1 image", encoder, encoderFlops(config, args.height, args.width),
             report.encoderReference());

  const Dust3rEncoding view1 = model.encode(image1), view2 = model.encode(image2);
  const Timing pair = timeCalls(args.warmup, args.repeats, [&] {
    const auto decoded = model.decode(view1, view2);
    pointMapFromRaw(model.headForward(0, decoded[0], args.height, args.width));
    pointMapFromRaw(model.headForward(1, decoded[1], args.height, args.width));
  });
  const int64_t tokens = view1.tokens.size(1);
  report.row(dtype_name, "DUSt3R decoder + 2 DPT heads, pair", pair,
             decoderFlops(config, tokens, tokens) + 2 * dptHeadFlops(config, args.height, args.width),
             report.pairReference());
  closeMemoryWindow(memory);
  printMemory(dtype_name, "DUSt3R", memory);
}

// FastForwardModel::forward for one query against N map tokens: ray MLP, decoder, query DPT
// head (with post-processing) and map head.
void benchFastForward(const BenchModelArguments& args, const Report& report, const std::string& dtype_name) {
  const at::ScalarType dtype = parseNetworkDtype(dtype_name);
  at::manual_seed(args.seed);
  FastForwardConfig ff_config;
  ff_config.dust3r = Dust3rConfig::preset(args.config);
  FastForwardModel model(ff_config);
  randomizeParameters(model.parameterTable(), args.seed, dtype);
  model.to(at::kCPU, dtype, dtype);
  MemoryReport memory = startMemoryWindow();
  const Dust3rConfig& config = model.config().dust3r;
  const Dust3rEncoding query = model.encode(at::rand({1, 3, args.height, args.width}) * 2 - 1);
  for (const int64_t count : args.map_tokens) {
    const MapTokens map = randomMapTokens(config, args.height / config.patch_size, args.width / config.patch_size,
                                          count, dtype, args.seed);
    const Timing forward = timeCalls(args.warmup, args.repeats, [&] { model.forward(query, map); });
    report.row(dtype_name, "FastForward decoder + query head, N=" + std::to_string(count), forward,
               fastForwardFlops(model.config(), args.height, args.width, count), nullptr);
  }
  closeMemoryWindow(memory);
  printMemory(dtype_name, "FastForward", memory);
}

void validate(const BenchModelArguments& args) {
  if (args.repeats < 1) throw InputError("--repeats: must be at least 1");
  if (args.warmup < 0) throw InputError("--warmup: must not be negative");
  if (args.threads < 0) throw InputError("--threads: must not be negative (0 = all hardware threads)");
  if (args.dtypes.empty()) throw InputError("--dtype: give at least one of fp32, bf16");
  for (const auto& dtype : args.dtypes) parseNetworkDtype(dtype);
  for (const int64_t count : args.map_tokens) {
    if (count < 1) throw InputError("--features: map token counts must be positive, got " + std::to_string(count));
  }
  Dust3rConfig config;
  try {
    config = Dust3rConfig::preset(args.config);
  } catch (const InputError& e) {
    throw InputError(std::string("--config: ") + e.what());
  }
  if (args.width <= 0 || args.height <= 0 || args.width % config.patch_size != 0 ||
      args.height % config.patch_size != 0) {
    throw InputError("--width/--height: " + std::to_string(args.width) + "x" + std::to_string(args.height) +
                     " is not a positive multiple of the patch size " + std::to_string(config.patch_size));
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

void runBenchModel(const BenchModelArguments& args) {
  validate(args);
  const int threads = setTorchThreadCount(args.threads);
  const std::string blas = setBlasThreads(threads);
  Report report(args, findReferenceTiming(args.reference));
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
  std::printf("load average at start: %s\n\n", loadAverage().c_str());

  report.header();
  for (const auto& dtype : args.dtypes) {
    benchDust3r(args, report, dtype);
    if (!args.map_tokens.empty()) benchFastForward(args, report, dtype);
  }
  std::printf("\nload average at end: %s\n", loadAverage().c_str());
}

}  // namespace

void registerBenchCommand(CLI::App& app, CommandRun& run) {
  CLI::App* bench = app.add_subcommand("bench", "Timings of the network on this machine");
  bench->require_subcommand(1);
  auto args = std::make_shared<BenchModelArguments>();
  CLI::App* cmd = bench->add_subcommand(
      "model", "CPU time, GFLOP/s and peak RSS of the encoder, the FastForward decoder + query head and "
               "DUSt3R's decoder + heads, with random weights, beside the Python reference timing");
  cmd->add_option("--config", args->config, "Network size: large (the official DUSt3R) or tiny")
      ->capture_default_str();
  cmd->add_option("--dtype", args->dtypes, "Network precisions, comma-separated: fp32, bf16 (bf16: encoder, decoder and DPT heads, as the reference under CPU autocast)")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "Intra-op and BLAS threads (0 = all hardware threads)")
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
  cmd->add_option("--seed", args->seed, "Seed of the random weights and inputs")->capture_default_str();
  cmd->callback([args, &run] {
    run = [args] {
      runBenchModel(*args);
      return 0;
    };
  });
}

}  // namespace ffloc::cli

#endif  // FFLOC_WITH_TORCH
