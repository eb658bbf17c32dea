// `ffloc bench model`: CPU timings of the network with random weights, beside the Python
// reference timing of the same DUSt3R configuration. Method and results: docs/benchmarks.md.
#ifdef FFLOC_WITH_TORCH

#include <ATen/Context.h>
#include <ATen/Parallel.h>
#include <ATen/TensorOperators.h>
#include <ATen/ops/cat.h>
#include <ATen/ops/empty.h>
#include <ATen/ops/ones.h>
#include <ATen/ops/rand.h>
#include <ATen/ops/randn.h>
#include <ATen/ops/zeros.h>
#include <dlfcn.h>
#include <sys/resource.h>
#include <torch/version.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <regex>
#include <string>
#include <vector>

#include "commands.h"
#include "ffloc/core/cpu_features.h"
#include "ffloc/core/error.h"
#include "ffloc/model/fastforward_model.h"
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

// The Python reference timing (fixtures/dust3r/python_reference_timing.txt), per dtype: the
// medians of each process and the median of all calls pooled, for the encoder and for the
// decoder + both DPT heads of a pair.
struct ReferenceRow {
  std::vector<double> process_medians;
  std::optional<double> pooled_median;
};
struct ReferenceTiming {
  std::filesystem::path path;
  std::map<std::string, ReferenceRow> encoder, pair;
};

// The setup the reference was measured with; other setups get no ratio.
constexpr const char* kReferenceConfig = "large";
constexpr int64_t kReferenceWidth = 512, kReferenceHeight = 384;

ReferenceTiming readReferenceTiming(const std::filesystem::path& path) {
  std::ifstream file(path);
  if (!file) throwInputError(path.string(), 0, "cannot open the reference timing file");
  const std::regex process(R"(^\s*(fp32|bf16) process \d+:\s*$)");
  const std::regex encoder(R"(^\s*\(i\)\s+encoder\b.*\bmedian ([0-9.]+) s\b)");
  const std::regex pair(R"(^\s*\(ii\)\s+decoder\b.*\bmedian ([0-9.]+) s\b)");
  const std::regex pooled(
      R"(^\s*(fp32|bf16) all calls pooled: encoder median ([0-9.]+) s\b.*decoder\+heads median ([0-9.]+) s\b)");
  ReferenceTiming reference;
  reference.path = path;
  std::string line, dtype;
  int line_number = 0, rows = 0;
  while (std::getline(file, line)) {
    ++line_number;
    std::smatch match;
    try {
      if (std::regex_search(line, match, process)) {
        dtype = match[1];
      } else if (!dtype.empty() && std::regex_search(line, match, encoder)) {
        reference.encoder[dtype].process_medians.push_back(std::stod(match[1]));
        ++rows;
      } else if (!dtype.empty() && std::regex_search(line, match, pair)) {
        reference.pair[dtype].process_medians.push_back(std::stod(match[1]));
        ++rows;
      } else if (std::regex_search(line, match, pooled)) {
        reference.encoder[match[1]].pooled_median = std::stod(match[2]);
        reference.pair[match[1]].pooled_median = std::stod(match[3]);
        ++rows;
      }
    } catch (const std::logic_error&) {
      throwInputError(path.string(), line_number, "malformed number in '" + line + "'");
    }
  }
  if (rows == 0) {
    throwInputError(path.string(), 0,
                    "no timing lines found (expected '(i) encoder ... median X s' under '<dtype> process N:' "
                    "or '<dtype> all calls pooled: ...')");
  }
  return reference;
}

// The explicit --reference, else the fixture under FFLOC_SHARED_DIR when it exists.
std::optional<ReferenceTiming> findReferenceTiming(const std::string& explicit_path) {
  if (!explicit_path.empty()) return readReferenceTiming(explicit_path);
  const char* shared = std::getenv("FFLOC_SHARED_DIR");
  if (!shared) return std::nullopt;
  const std::filesystem::path path =
      std::filesystem::path(shared) / "fixtures" / "dust3r" / "python_reference_timing.txt";
  if (!std::filesystem::exists(path)) return std::nullopt;
  return readReferenceTiming(path);
}

at::ScalarType parseDtype(const std::string& name) {
  if (name == "fp32") return at::kFloat;
  if (name == "bf16") return at::kBFloat16;
  throw InputError("--dtype: unknown dtype '" + name + "' (expected fp32 or bf16)");
}

// Timings do not depend on the weights' values as long as activations stay finite and of
// ordinary size (denormals or overflow would change the speed): variance-preserving uniform
// weights, unit norm scales, zero biases. Each tensor is cast as soon as it is drawn so that a
// bf16 model never holds a float32 copy of itself.
void fillRandomParameters(const ParameterTable& table, at::ScalarType dtype) {
  const at::TensorOptions f32 = at::TensorOptions().dtype(at::kFloat);
  const auto ends_with = [](const std::string& text, const std::string& suffix) {
    return text.size() >= suffix.size() && text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
  };
  for (const auto& entry : table.entries()) {
    at::Tensor value;
    if (entry.shape.size() == 1 && ends_with(entry.name, ".weight")) {
      value = at::ones(entry.shape, f32);
    } else if (entry.shape.size() == 1) {
      value = at::zeros(entry.shape, f32);
    } else {
      value = at::empty(entry.shape, f32);
      const double fan_in = static_cast<double>(value.numel() / entry.shape[0]);
      const double bound = std::sqrt(3.0 / fan_in);
      value.uniform_(-bound, bound);
    }
    *entry.tensor = value.to(dtype);
  }
}

// `count` map tokens sampled with the production code path (sampleMapTokenIndices +
// gatherMapTokens) from mapping images of random encoder tokens and random rays.
MapTokens randomMapTokens(const Dust3rConfig& config, int64_t rows, int64_t cols, int64_t count,
                          at::ScalarType dtype, uint64_t seed) {
  const int64_t per_image = rows * cols;
  // At least a handful of images, as after retrieval, and enough to hold all N tokens.
  const int64_t images = std::max<int64_t>(8, (count + per_image - 1) / per_image);
  std::vector<Dust3rEncoding> encodings;
  std::vector<at::Tensor> rays;
  for (int64_t k = 0; k < images; ++k) {
    Dust3rEncoding encoding;
    encoding.tokens = at::randn({1, per_image, config.enc_dim}).to(dtype);
    encoding.positions = patchPositions(1, rows, cols, at::kCPU);
    encoding.height = rows * config.patch_size;
    encoding.width = cols * config.patch_size;
    encodings.push_back(encoding);
    at::Tensor direction = at::randn({1, per_image, 3});
    direction = direction / direction.norm(2, {-1}, /*keepdim=*/true);
    rays.push_back(at::cat({at::rand({1, per_image, 3}) * 2 - 1, direction}, -1));
  }
  const std::vector<int64_t> tokens_per_image(static_cast<size_t>(images), per_image);
  return gatherMapTokens(encodings, rays, sampleMapTokenIndices(tokens_per_image, count, seed));
}

struct Timing {
  std::vector<double> seconds;

  double median() const {
    std::vector<double> sorted = seconds;
    std::sort(sorted.begin(), sorted.end());
    const size_t n = sorted.size();
    return n % 2 == 1 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);
  }
  double min() const { return *std::min_element(seconds.begin(), seconds.end()); }
  double max() const { return *std::max_element(seconds.begin(), seconds.end()); }
};

Timing timeCalls(int warmup, int repeats, const std::function<void()>& call) {
  for (int i = 0; i < warmup; ++i) call();
  Timing timing;
  for (int i = 0; i < repeats; ++i) {
    const auto start = std::chrono::steady_clock::now();
    call();
    timing.seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  return timing;
}

// A "Vm...:   <n> kB" line of /proc/self/status, in MiB.
std::optional<double> procStatusMiB(const std::string& key) {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind(key + ":", 0) == 0) return std::stod(line.substr(key.size() + 1)) / 1024.0;
  }
  return std::nullopt;
}

// Resets the peak RSS (VmHWM) to the current RSS (Linux >= 4.0), so that each model reports its
// own peak; false where the kernel refuses.
bool resetPeakRss() {
  std::ofstream clear("/proc/self/clear_refs");
  clear << "5";
  clear.flush();
  return static_cast<bool>(clear);
}

// The process-wide peak where /proc is missing: ru_maxrss (KiB on Linux).
double processPeakRssMiB() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;
}

struct MemoryReport {
  double after_build_mib = 0.0;
  double peak_mib = 0.0;
  bool peak_is_per_model = false;
};

std::string loadAverage() {
  double load[3] = {0.0, 0.0, 0.0};
  if (getloadavg(load, 3) != 3) return "unknown";
  char text[64];
  std::snprintf(text, sizeof(text), "%.2f %.2f %.2f", load[0], load[1], load[2]);
  return text;
}

// fp32 matmuls go to the system BLAS, which keeps its own thread pool: on Debian that is
// OpenBLAS, reached here through the symbols libtorch already links. Returns what it is and the
// kernel family it picked for this CPU.
std::string setBlasThreads(int threads) {
  using SetThreads = void (*)(int);
  using GetString = char* (*)();
  const auto set = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"));
  const auto core = reinterpret_cast<GetString>(dlsym(RTLD_DEFAULT, "openblas_get_corename"));
  if (!set) return "not OpenBLAS (thread count left as is)";
  set(threads);
  return std::string("OpenBLAS, core ") + (core ? core() : "unknown") + ", " + std::to_string(threads) + " threads";
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

// Starts the peak-RSS window for a freshly built model.
MemoryReport startMemoryWindow() {
  MemoryReport memory;
  memory.after_build_mib = procStatusMiB("VmRSS").value_or(0.0);
  memory.peak_is_per_model = resetPeakRss() && procStatusMiB("VmHWM").has_value();
  return memory;
}

void closeMemoryWindow(MemoryReport& memory) {
  memory.peak_mib = memory.peak_is_per_model ? *procStatusMiB("VmHWM") : processPeakRssMiB();
}

// Encoder on one image and DUSt3R's decoder + both DPT heads (with post-processing) on a pair:
// the two measurements of the Python reference.
void benchDust3r(const BenchModelArguments& args, const Report& report, const std::string& dtype_name) {
  const at::ScalarType dtype = parseDtype(dtype_name);
  at::manual_seed(args.seed);
  Dust3rModel model(Dust3rConfig::preset(args.config));
  fillRandomParameters(model.parameterTable(), dtype);
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
  const at::ScalarType dtype = parseDtype(dtype_name);
  at::manual_seed(args.seed);
  FastForwardConfig ff_config;
  ff_config.dust3r = Dust3rConfig::preset(args.config);
  FastForwardModel model(ff_config);
  fillRandomParameters(model.parameterTable(), dtype);
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
  for (const auto& dtype : args.dtypes) parseDtype(dtype);
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
