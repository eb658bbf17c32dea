#include "ffloc/model/model_loader.h"

#include <ATen/core/Tensor.h>
#include <ATen/ops/empty.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <charconv>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "ffloc/core/cpu_features.h"
#include "ffloc/core/error.h"
#include "ffloc/core/hash.h"
#include "ffloc/core/random.h"
#include "ffloc/io/json_fields.h"
#include "ffloc/io/tensor_checksums.h"
#include "ffloc/model/parameter_table.h"
#include "ffloc/model/tensor_conversion.h"
#include "ffloc/model/torch_threads.h"

namespace ffloc {
namespace {

uint64_t hashString(const std::string& text, uint64_t seed = 0xcbf29ce484222325ULL) {
  return fnv1a64(reinterpret_cast<const uint8_t*>(text.data()), text.size(), seed);
}

std::string sizesName(const Dust3rConfig& c) {
  return "e" + std::to_string(c.enc_dim) + "x" + std::to_string(c.enc_depth) + "-d" + std::to_string(c.dec_dim) +
         "x" + std::to_string(c.dec_depth);
}

bool sameSizes(const Dust3rConfig& a, const Dust3rConfig& b) {
  return a.patch_size == b.patch_size && a.enc_dim == b.enc_dim && a.enc_depth == b.enc_depth &&
         a.dec_dim == b.dec_dim && a.dec_depth == b.dec_depth && a.mlp_ratio == b.mlp_ratio &&
         a.head.layer_dims == b.head.layer_dims && a.head.feature_dim == b.head.feature_dim &&
         a.head.last_dim == b.head.last_dim;
}

// Head counts are invisible in tensor shapes. A checkpoint with the sizes of a known preset gets
// that preset's heads (the tiny fixture's head dims are 16 and 12); anything else gets DUSt3R's
// head dim of 64.
Dust3rConfig configFromArchive(const TensorArchive& archive) {
  for (const char* name : {"large", "small", "tiny"}) {
    const Dust3rConfig preset = Dust3rConfig::preset(name);
    Dust3rConfigInference heads;
    heads.enc_head_dim = preset.enc_dim / preset.enc_heads;
    heads.dec_head_dim = preset.dec_dim / preset.dec_heads;
    try {
      const Dust3rConfig inferred = inferDust3rConfig(archive, heads);
      if (sameSizes(inferred, preset)) return inferred;
    } catch (const InputError&) {
      // Not this preset; the generic inference below reports what is wrong.
    }
  }
  return inferDust3rConfig(archive);
}

// A trained checkpoint records the image size it learned on (metadata 'input_long_side');
// checkpoints without it are taken to be at DUSt3R's 512.
int64_t inputLongSide(const TensorArchive& archive, int64_t patch_size) {
  const auto found = archive.metadata().find("input_long_side");
  if (found == archive.metadata().end()) return 512;
  char* end = nullptr;
  const long long value = std::strtoll(found->second.c_str(), &end, 10);
  if (found->second.empty() || *end != '\0' || value < patch_size || value > 8192) {
    throwInputError(archive.path().string(), 0,
                    "metadata 'input_long_side': expected an image size of at least the patch size " +
                        std::to_string(patch_size) + ", got '" + found->second + "'");
  }
  return value;
}

// The identity's size part: the network's widths and depths, and its family.
std::string sizesName(const FastForwardConfig& c) {
  return (c.encoder == TokenEncoderKind::kDenseSift ? "sift-" : "") + sizesName(c.dust3r);
}

struct RandomModelSpec {
  std::string preset;
  uint64_t seed = 0;
  FastForwardConfig config;
  std::string problem;  // why the spec is not one, naming it
};

// "random:<preset>[:<seed>]"
RandomModelSpec parseRandomModelSpec(const std::string& spec) {
  RandomModelSpec parsed;
  const std::string rest = spec.substr(std::strlen("random:"));
  const size_t colon = rest.find(':');
  parsed.preset = rest.substr(0, colon);
  if (colon != std::string::npos) {
    const std::string text = rest.substr(colon + 1);
    // strtoull wrapped -1 to 2^64 - 1 and clamped larger numbers to it: two specs, one model.
    const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), parsed.seed);
    if (text.empty() || error != std::errc() || end != text.data() + text.size()) {
      parsed.problem = "'" + spec + "': seed must be a whole number in [0, 18446744073709551615]";
      return parsed;
    }
  }
  try {
    parsed.config = FastForwardConfig::preset(parsed.preset);
  } catch (const InputError&) {
    parsed.problem = "'" + spec + "': unknown preset '" + parsed.preset +
                     "' (expected tiny, small, large, sift-tiny or sift-small)";
  }
  return parsed;
}

// "<origin>/<sizes>/<fingerprint>": the fingerprint covers the parameters and the whole
// architecture, preprocessing included. Of the parameters alone, a checkpoint whose metadata
// changed its dense-SIFT window sizes or input size was taken for the model a map was built with,
// and localized nothing.
std::string modelIdentity(const std::string& origin, FastForwardModel& model) {
  const uint64_t fingerprint = hashString(toJson(model.config()).dump(), parameterFingerprint(model));
  return origin + "/" + sizesName(model.config()) + "/" + hex64(fingerprint);
}

LoadedModel randomModel(const std::string& spec) {
  const RandomModelSpec parsed = parseRandomModelSpec(spec);
  const std::string& preset = parsed.preset;
  const uint64_t seed = parsed.seed;
  const FastForwardConfig& config = parsed.config;
  LoadedModel loaded;
  loaded.model = std::make_unique<FastForwardModel>(config);
  randomizeParameters(*loaded.model, seed);
  loaded.id = modelIdentity("random-" + preset, *loaded.model);
  if (config.query_head == QueryHeadKind::kMatching) {
    loaded.model->initializeMatchingHeadAsNearestNeighbour();
    loaded.id = modelIdentity("init-" + preset, *loaded.model);
    loaded.description = "untrained " + preset + " FastForward (seed " + std::to_string(seed) +
                         "): nearest-neighbour matching of its dense-SIFT tokens";
  } else {
    loaded.description = "random " + preset + " FastForward (seed " + std::to_string(seed) + ", untrained)";
  }
  return loaded;
}

}  // namespace

void randomizeParameters(const ParameterTable& table, uint64_t seed, at::ScalarType dtype) {
  const at::TensorOptions f32 = at::TensorOptions().dtype(at::kFloat);
  for (const ParameterTable::Entry& entry : table.entries()) {
    at::Tensor tensor = at::empty(entry.shape, f32);
    // Seeded per name, so a tensor's values do not depend on the registration order.
    Rng rng(hashString(entry.name, seed ^ 0x5eedULL));
    float* data = tensor.data_ptr<float>();
    const int64_t count = tensor.numel();
    const bool is_bias = entry.name.size() >= 5 && entry.name.compare(entry.name.size() - 5, 5, ".bias") == 0;
    if (is_bias) {
      for (int64_t i = 0; i < count; ++i) data[i] = 0.02f * static_cast<float>(rng.uniform(-1.0, 1.0));
    } else if (entry.shape.size() == 1) {
      for (int64_t i = 0; i < count; ++i) data[i] = 1.0f + 0.1f * static_cast<float>(rng.uniform(-1.0, 1.0));  // LayerNorm gain
    } else {
      const int64_t fan_in = entry.shape.empty() || entry.shape[0] == 0 ? 1 : std::max<int64_t>(1, count / entry.shape[0]);
      const float bound = static_cast<float>(std::sqrt(3.0 / static_cast<double>(fan_in)));
      for (int64_t i = 0; i < count; ++i) data[i] = bound * static_cast<float>(rng.uniform(-1.0, 1.0));
    }
    // Cast as soon as drawn: a bf16 model never holds a float32 copy of itself.
    *entry.tensor = dtype == at::kFloat ? tensor : tensor.to(dtype);
  }
}

void randomizeParameters(FastForwardModel& model, uint64_t seed) {
  randomizeParameters(model.parameterTable(), seed, at::kFloat);
  model.to(at::kCPU, at::kFloat);
}

uint64_t parameterFingerprint(FastForwardModel& model) {
  uint64_t hash = 0xcbf29ce484222325ULL;
  const ParameterTable table = model.parameterTable();
  for (const ParameterTable::Entry& entry : table.entries()) {
    hash = hashString(entry.name, hash);
    const at::Tensor values = entry.tensor->to(at::kFloat).contiguous();
    // FNV-1a over 64-bit words: the large model has 2.3 GB of parameters, and byte-wise FNV
    // would take seconds on every load.
    const auto* bytes = static_cast<const uint8_t*>(values.data_ptr());
    const size_t size = static_cast<size_t>(values.numel()) * sizeof(float);
    const size_t words = size / 8;
    for (size_t i = 0; i < words; ++i) {
      uint64_t word;
      std::memcpy(&word, bytes + 8 * i, 8);
      hash = (hash ^ word) * 0x100000001b3ULL;
      hash ^= hash >> 32;
    }
    hash = fnv1a64(bytes + 8 * words, size - 8 * words, hash);
  }
  return hash;
}

void saveModel(FastForwardModel& model, const std::filesystem::path& path, std::map<std::string, std::string> metadata) {
  metadata["format"] = "ffloc-fastforward";
  metadata["input_long_side"] = std::to_string(model.config().input_long_side);
  metadata["architecture"] = toJson(model.config()).dump();
  std::vector<std::pair<std::string, at::Tensor>> weights;
  const ParameterTable table = model.parameterTable();
  for (const auto& entry : table.entries()) weights.emplace_back(entry.name, *entry.tensor);
  writeFloatTensors(path, weights, metadata);
}

std::string readLatestCheckpointName(const std::filesystem::path& latest_file) {
  std::ifstream in(latest_file);
  std::string name;
  std::getline(in, name);
  return name;
}

bool isCheckpointFolderName(const std::string& name) {
  return name.rfind("step_", 0) == 0 && name.find('/') == std::string::npos;
}

std::string defaultModelPath() {
  const char* override_path = std::getenv("FFLOC_MODEL");
  if (override_path != nullptr && *override_path != '\0') return override_path;
  return FFLOC_SHIPPED_MODEL;
}

std::string modelSpecProblem(const std::string& requested) {
  if (requested.rfind("random:", 0) == 0) return parseRandomModelSpec(requested).problem;
  const std::string path = requested == "default" ? defaultModelPath() : requested;
  std::error_code error;
  const std::filesystem::file_status status = std::filesystem::status(path, error);
  if (requested == "default" && status.type() != std::filesystem::file_type::regular) {
    const char* override_path = std::getenv("FFLOC_MODEL");
    if (override_path != nullptr && *override_path != '\0')
      return "the default model is FFLOC_MODEL's '" + path + "', which is not a file";
    return "the default model '" + path + "' is missing (set FFLOC_MODEL or name a model file; docs/training.md trains one)";
  }
  if (status.type() == std::filesystem::file_type::not_found) return "'" + path + "': no such file";
  if (error) return "'" + path + "': " + error.message();
  if (status.type() == std::filesystem::file_type::directory) {
    // A training checkpoint's folder, or a run's: the weights are a file inside.
    const std::filesystem::path folder(path);
    std::filesystem::path inside = folder / "model.safetensors";
    for (const std::filesystem::path& latest : {folder / "latest", folder / "checkpoints" / "latest"}) {
      const std::string step = readLatestCheckpointName(latest);
      if (isCheckpointFolderName(step)) inside = latest.parent_path() / step / "model.safetensors";
    }
    if (std::filesystem::is_regular_file(inside, error))
      return "'" + path + "': a folder, not a weights file; its model is '" + inside.string() + "'";
    return "'" + path + "': a folder, not a weights file";
  }
  if (status.type() != std::filesystem::file_type::regular)
    return "'" + path + "': not a regular file (FIFO, device or socket)";
  return "";
}

LoadedModel loadModel(const std::string& requested, const ModelLoadOptions& options) {
  if (const std::string problem = modelSpecProblem(requested); !problem.empty()) throwInputError("model", 0, problem);
  const std::string spec = requested == "default" ? defaultModelPath() : requested;
  if (options.dtype != at::kFloat && options.dtype != at::kBFloat16)
    throwInputError("model", 0, "network dtype must be float32 or bfloat16");
  if (options.dtype == at::kBFloat16 && !cpuHasNativeBfloat16()) {
    std::fprintf(stderr, "note: this CPU has neither AMX nor AVX512-BF16, so the bf16 network computes in float32 here: "
                 "half float32's weight memory, none of its speed-up (docs/benchmarks.md)\n");
  }
  LoadedModel loaded;
  if (spec.rfind("random:", 0) == 0) {
    loaded = randomModel(spec);
  } else {
    const auto archive = openTensorArchive(spec);
    verifyChecksums(*archive, torchThreadCount());
    // Given the optimizer state, the loader reported the model's first tensor missing.
    if (const auto format = archive->metadata().find("format");
        format != archive->metadata().end() && format->second == kTrainingStateFormat) {
      throwInputError(spec, 0, "a training checkpoint's optimizer state, not a model; the model is the "
                               "model.safetensors beside it");
    }
    const auto architecture = archive->metadata().find("architecture");
    FastForwardConfig config;
    if (architecture != archive->metadata().end() && archive->contains("map_head.weight")) {
      const std::string source = spec + ": metadata 'architecture'";
      config = fastForwardConfigFromJson(parseJson(architecture->second, source), source);
      loaded.model = std::make_unique<FastForwardModel>(config);
      loaded.model->loadWeights(*archive);
      loaded.id = modelIdentity("fastforward", *loaded.model);
      loaded.description = "FastForward checkpoint " + spec;
      loaded.model->to(at::kCPU, options.dtype, options.dtype);
      return loaded;
    }
    config.dust3r = configFromArchive(*archive);
    if (archive->contains("map_head.weight")) {
      const TensorView& fc1 = archive->at("ray_embed.fc1.weight");
      if (fc1.shape.size() != 2) throwInputError(spec, 0, "tensor 'ray_embed.fc1.weight': expected 2 dimensions");
      if (fc1.shape[0] != config.dust3r.enc_dim) config.rays.hidden_dim = fc1.shape[0];
      config.input_long_side = inputLongSide(*archive, config.dust3r.patch_size);
      loaded.model = std::make_unique<FastForwardModel>(config);
      loaded.model->loadWeights(*archive);
      loaded.id = modelIdentity("fastforward", *loaded.model);
      loaded.description = "FastForward checkpoint " + spec;
    } else if (archive->contains("downstream_head1.dpt.head.4.weight")) {
      loaded.model = std::make_unique<FastForwardModel>(config);
      loaded.model->initializeFromDust3r(*archive, options.init_seed);
      loaded.id = modelIdentity("dust3r-init", *loaded.model);
      loaded.description = "FastForward initialised from DUSt3R checkpoint " + spec +
                           " (ray MLP and map head untrained)";
    } else {
      throwInputError(spec, 0,
                      "model weights: neither a FastForward checkpoint (no 'map_head.weight') nor a DUSt3R "
                      "checkpoint (no 'downstream_head1.dpt.head.4.weight')");
    }
  }
  loaded.model->to(at::kCPU, options.dtype, options.dtype);
  return loaded;
}

}  // namespace ffloc
