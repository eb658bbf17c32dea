#include "ffloc/train/training_config.h"

#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <type_traits>
#include <utility>

#include <torch/cuda.h>

#include "ffloc/core/error.h"
#include "ffloc/core/threads.h"
#include "ffloc/data/format_io.h"
#include "ffloc/io/json_fields.h"

namespace ffloc {

namespace {

// A JSON value that its field's type cannot hold; the message follows "field '<key>': ".
class FieldValueError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

std::string wrongType(const nlohmann::json& value) { return "wrong type (" + value.dump() + ")"; }

// nlohmann's get<int>() truncated 1.5 to 1, turned 1e30 into 0 and wrapped -1 to 2^64 - 1 for an
// unsigned field: an integer field takes a number only when it holds that number exactly. An
// integral float (1e3) is a number like any other.
template <typename T>
T integerFrom(const nlohmann::json& value) {
  constexpr T lowest = std::numeric_limits<T>::min(), highest = std::numeric_limits<T>::max();
  const auto tooLarge = [&] {
    return FieldValueError(value.dump() + " is too large (at most " + std::to_string(highest) + ")");
  };
  const auto tooSmall = [&] {
    return FieldValueError(value.dump() + " is too small (at least " + std::to_string(lowest) + ")");
  };
  if (value.is_number_unsigned()) {
    const uint64_t number = value.get<uint64_t>();
    if (number > static_cast<uint64_t>(highest)) throw tooLarge();
    return static_cast<T>(number);
  }
  if (value.is_number_integer()) {
    const int64_t number = value.get<int64_t>();
    if (number < 0 && number < static_cast<int64_t>(lowest)) throw tooSmall();
    if (number > 0 && static_cast<uint64_t>(number) > static_cast<uint64_t>(highest)) throw tooLarge();
    return static_cast<T>(number);
  }
  if (value.is_number_float()) {
    const double number = value.get<double>();
    if (!std::isfinite(number) || number != std::floor(number)) {
      throw FieldValueError("expected an integer, got " + value.dump());
    }
    if (number < static_cast<double>(lowest)) throw tooSmall();
    // highest + 1 is a power of two, which a double holds exactly.
    if (number >= static_cast<double>(highest) + 1.0) throw tooLarge();
    return static_cast<T>(number);
  }
  throw FieldValueError(wrongType(value));
}

// One accessor per field, so reading, writing and the unknown-key check share one list.
struct FieldBinding {
  std::function<void(TrainingConfig&, const nlohmann::json&)> read;
  std::function<nlohmann::json(const TrainingConfig&)> write;
};

template <typename T>
FieldBinding bindField(T TrainingConfig::*member) {
  return {[member](TrainingConfig& config, const nlohmann::json& value) {
            if constexpr (std::is_integral_v<T> && !std::is_same_v<T, bool>) {
              config.*member = integerFrom<T>(value);
            } else {
              config.*member = value.get<T>();
            }
          },
          [member](const TrainingConfig& config) { return nlohmann::json(config.*member); }};
}

const std::map<std::string, FieldBinding>& fieldBindings() {
  static const std::map<std::string, FieldBinding> bindings = {
      {"model", bindField(&TrainingConfig::model)},
      {"model_seed", bindField(&TrainingConfig::model_seed)},
      {"mapping_frames", bindField(&TrainingConfig::mapping_frames)},
      {"min_map_tokens", bindField(&TrainingConfig::min_map_tokens)},
      {"max_map_tokens", bindField(&TrainingConfig::max_map_tokens)},
      {"min_overlap", bindField(&TrainingConfig::min_overlap)},
      {"max_overlap", bindField(&TrainingConfig::max_overlap)},
      {"overlap_candidates", bindField(&TrainingConfig::overlap_candidates)},
      {"overlap_stride", bindField(&TrainingConfig::overlap_stride)},
      {"long_side", bindField(&TrainingConfig::long_side)},
      {"colour_jitter", bindField(&TrainingConfig::colour_jitter)},
      {"alpha", bindField(&TrainingConfig::alpha)},
      {"match_weight", bindField(&TrainingConfig::match_weight)},
      {"match_radius", bindField(&TrainingConfig::match_radius)},
      {"point_weight", bindField(&TrainingConfig::point_weight)},
      {"steps", bindField(&TrainingConfig::steps)},
      {"warmup_steps", bindField(&TrainingConfig::warmup_steps)},
      {"learning_rate", bindField(&TrainingConfig::learning_rate)},
      {"min_learning_rate", bindField(&TrainingConfig::min_learning_rate)},
      {"weight_decay", bindField(&TrainingConfig::weight_decay)},
      {"beta1", bindField(&TrainingConfig::beta1)},
      {"beta2", bindField(&TrainingConfig::beta2)},
      {"adam_epsilon", bindField(&TrainingConfig::adam_epsilon)},
      {"clip_grad_norm", bindField(&TrainingConfig::clip_grad_norm)},
      {"train_encoder", bindField(&TrainingConfig::train_encoder)},
      {"trained_parameters", bindField(&TrainingConfig::trained_parameters)},
      {"batch_size", bindField(&TrainingConfig::batch_size)},
      {"accumulate", bindField(&TrainingConfig::accumulate)},
      {"loader_threads", bindField(&TrainingConfig::loader_threads)},
      {"prefetch_samples", bindField(&TrainingConfig::prefetch_samples)},
      {"seed", bindField(&TrainingConfig::seed)},
      {"validation_seed", bindField(&TrainingConfig::validation_seed)},
      {"threads", bindField(&TrainingConfig::threads)},
      {"device", bindField(&TrainingConfig::device)},
      {"precision", bindField(&TrainingConfig::precision)},
      {"log_every", bindField(&TrainingConfig::log_every)},
      {"checkpoint_every", bindField(&TrainingConfig::checkpoint_every)},
      {"keep_checkpoints", bindField(&TrainingConfig::keep_checkpoints)},
      {"validation_every", bindField(&TrainingConfig::validation_every)},
      {"validation_samples", bindField(&TrainingConfig::validation_samples)},
  };
  return bindings;
}

}  // namespace

std::optional<TrainingConfigProblem> TrainingConfig::problem() const {
  if (auto found = settingsProblem()) return found;
  // Here, before any tensor: libtorch's own refusal is a stack trace from deep inside the run.
  if (device == "cuda" && !torch::cuda::is_available()) {
    return TrainingConfigProblem{"device", "cuda, but this libtorch was built without CUDA or sees no GPU; use cpu"};
  }
  return std::nullopt;
}

std::optional<TrainingConfigProblem> TrainingConfig::settingsProblem() const {
  std::optional<TrainingConfigProblem> first;
  const auto fail = [&](const std::string& field, const std::string& what) {
    if (!first) first = TrainingConfigProblem{field, what};
  };
  // Upper bounds keep a sample's memory bounded before any is prepared: long_side 100000 once
  // grew to 24 GB before the kernel killed the run. Attention over an image's tokens grows as
  // the fourth power of the long side; 2048 is four times DUSt3R's 512.
  if (mapping_frames < 1 || mapping_frames > 64) fail("mapping_frames", "must be in [1, 64]");
  if (min_map_tokens < 1 || max_map_tokens < min_map_tokens) {
    fail(min_map_tokens < 1 ? "min_map_tokens" : "max_map_tokens", "need 1 <= min_map_tokens <= max_map_tokens");
  }
  if (max_map_tokens > 100000) fail("max_map_tokens", "must be at most 100000");
  if (!(min_overlap >= 0 && min_overlap <= max_overlap && max_overlap <= 1)) {
    // A negative min_overlap was blamed on max_overlap.
    fail(min_overlap >= 0 && min_overlap <= 1 ? "max_overlap" : "min_overlap", "need 0 <= min_overlap <= max_overlap <= 1");
  }
  if (overlap_candidates < mapping_frames) fail("overlap_candidates", "must be at least mapping_frames");
  // A stride past the image sampled no pixel, and every draw failed on overlap.
  if (overlap_stride < 1 || overlap_stride > long_side)
    fail("overlap_stride", "must be in [1, long_side (" + std::to_string(long_side) + ")], got " +
                               std::to_string(overlap_stride));
  if (long_side < 16 || long_side > 2048) fail("long_side", "must be in [16, 2048] pixels, got " + std::to_string(long_side));
  if (!(colour_jitter >= 0 && colour_jitter < 1)) fail("colour_jitter", "must be in [0, 1)");
  // The loss and the optimiser run in float32: the upper bounds below keep every product of a
  // setting with a loss, gradient or weight finite (alpha 1e300 made the loss -inf, weight_decay
  // 1e300 and learning_rate 1e10 the weights non-finite, learning_rate 1e39 overflowed float).
  if (!(alpha > 0 && alpha <= 1e3)) fail("alpha", "must be in (0, 1000], got " + formatNumber(alpha));
  if (!(match_weight >= 0 && match_weight <= 1e3)) fail("match_weight", "must be in [0, 1000]");
  if (!(match_radius > 0 && match_radius <= 16)) fail("match_radius", "must be in (0, 16] patch footprints");
  if (!(point_weight >= 0 && point_weight <= 1e3)) fail("point_weight", "must be in [0, 1000]");
  for (const std::string& prefix : trained_parameters) {
    if (prefix.empty()) fail("trained_parameters", "an empty prefix would name every parameter; leave the list empty instead");
  }
  // A billion steps is years on any machine; past it a value is a typo.
  if (steps < 1 || steps > 1000000000) fail("steps", "must be in [1, 1000000000], got " + std::to_string(steps));
  if (warmup_steps < 0) fail("warmup_steps", "must be at least 0, got " + std::to_string(warmup_steps));
  if (warmup_steps > steps) {
    const bool by_default = warmup_steps == TrainingConfig{}.warmup_steps;
    fail("warmup_steps", "must be at most steps (" + std::to_string(steps) + "), got " + std::to_string(warmup_steps) +
                             (by_default ? ", the default" : "") + ": set warmup_steps to at most " +
                             std::to_string(steps) + " for a run this short");
  }
  if (!(learning_rate > 0 && learning_rate <= 1)) fail("learning_rate", "must be in (0, 1], got " + formatNumber(learning_rate));
  if (!(min_learning_rate >= 0 && min_learning_rate <= learning_rate)) {
    fail("min_learning_rate", "must be in [0, learning_rate], got " + formatNumber(min_learning_rate));
  }
  // AdamW scales the weights by 1 - lr x weight_decay each step: with both at most 1 that stays
  // in [0, 1].
  if (!(weight_decay >= 0 && weight_decay <= 1)) fail("weight_decay", "must be in [0, 1], got " + formatNumber(weight_decay));
  if (!(beta1 >= 0 && beta1 < 1)) fail("beta1", "must be in [0, 1)");
  if (!(beta2 >= 0 && beta2 < 1)) fail("beta2", "must be in [0, 1)");
  // Added to float32 moments: below float's smallest normal number (1.2e-38) it rounds to 0, and
  // a parameter without gradient then divides 0 by 0.
  if (!(adam_epsilon >= 1e-30 && adam_epsilon <= 1)) {
    fail("adam_epsilon", "must be in [1e-30, 1], got " + formatNumber(adam_epsilon));
  }
  if (!(clip_grad_norm >= 0 && clip_grad_norm <= 1e6)) {
    fail("clip_grad_norm", "must be in [0, 1e6] (0: off), got " + formatNumber(clip_grad_norm));
  }
  if (batch_size < 1 || batch_size > 1024) fail("batch_size", "must be in [1, 1024]");
  // Every pass is a forward and backward pass: a billion of them made one step run for days.
  if (accumulate < 1 || accumulate > 1024) fail("accumulate", "must be in [1, 1024], got " + std::to_string(accumulate));
  if (loader_threads < 1 || loader_threads > 256) fail("loader_threads", "must be in [1, 256]");
  if (prefetch_samples < 1 || prefetch_samples > 1024) fail("prefetch_samples", "must be in [1, 1024]");
  if (const std::string problem = threadCountProblem(threads); !problem.empty()) fail("threads", problem);
  if (device != "cpu" && device != "cuda") fail("device", "must be cpu or cuda");
  if (precision != "fp32" && precision != "bf16") fail("precision", "must be fp32 or bf16");
  if (log_every < 1) fail("log_every", "must be positive");
  if (checkpoint_every < 1) fail("checkpoint_every", "must be positive");
  if (keep_checkpoints < 1) fail("keep_checkpoints", "must be at least 1");
  if (validation_every < 0) fail("validation_every", "must be non-negative (0: off)");
  // Each is a forward pass and a PnP at every validation: a billion of them never finished one.
  if (validation_samples < 1 || validation_samples > 100000)
    fail("validation_samples", "must be in [1, 100000], got " + std::to_string(validation_samples));
  return first;
}

TrainingConfigError::TrainingConfigError(const std::string& origin, TrainingConfigProblem problem)
    : InputError(locate(origin, 0, "field '" + problem.field + "': " + problem.message)), problem_(std::move(problem)) {}

void TrainingConfig::validate(const std::string& origin) const {
  if (const auto found = problem()) throw TrainingConfigError(origin, *found);
}

TrainingConfig trainingConfigFromJson(const nlohmann::json& json, const std::string& origin) {
  if (!json.is_object()) throwInputError(origin, 0, "expected a JSON object of training settings");
  TrainingConfig config;
  for (const auto& [key, value] : json.items()) {
    const auto binding = fieldBindings().find(key);
    if (binding == fieldBindings().end()) throwInputError(origin, 0, "field '" + key + "': unknown setting");
    try {
      binding->second.read(config, value);
    } catch (const FieldValueError& e) {
      throwInputError(origin, 0, "field '" + key + "': " + e.what());
    } catch (const nlohmann::json::exception&) {
      throwInputError(origin, 0, "field '" + key + "': " + wrongType(value));
    }
  }
  if (const auto found = config.settingsProblem()) throw TrainingConfigError(origin, *found);
  return config;
}

TrainingConfig readTrainingConfig(const std::filesystem::path& file) {
  return trainingConfigFromJson(parseJsonFile(file), file.string());
}

nlohmann::json toJson(const TrainingConfig& config) {
  nlohmann::json json = nlohmann::json::object();
  for (const auto& [key, binding] : fieldBindings()) json[key] = binding.write(config);
  return json;
}

std::optional<std::string> firstDifferingField(const nlohmann::json& a, const nlohmann::json& b,
                                               const std::set<std::string>& ignored) {
  for (const auto& [field, value] : a.items())
    if (!ignored.count(field) && !(b.contains(field) && b.at(field) == value)) return field;
  return std::nullopt;
}

}  // namespace ffloc
