#include "ffloc/train/trainer.h"

#include <ATen/TensorOperators.h>
#include <c10/core/GradMode.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "ffloc/core/cpu_features.h"
#include "ffloc/core/error.h"
#include "ffloc/model/torch_threads.h"
#include "ffloc/model/model_loader.h"
#include "ffloc/pose/pnp.h"
#include "ffloc/train/autocast.h"
#include "ffloc/train/confidence_loss.h"
#include "ffloc/train/training_checkpoint.h"

namespace ffloc {

namespace {

uint64_t splitMix(uint64_t z) {
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// Settings that may change between a run and its resumption: they do not alter what the
// optimiser sees (the step count changes the schedule's length, which is the user's call).
const std::set<std::string>& resumableFields() {
  static const std::set<std::string> fields = {"steps",           "log_every",        "checkpoint_every",
                                               "keep_checkpoints", "validation_every", "validation_samples",
                                               "threads",         "device",           "precision"};
  return fields;
}

void checkResumable(const TrainingConfig& stored, const TrainingConfig& requested, const std::string& origin) {
  const nlohmann::json a = toJson(stored), b = toJson(requested);
  for (const auto& [key, value] : a.items()) {
    if (resumableFields().count(key) || b.at(key) == value) continue;
    throwInputError(origin, 0, "field '" + key + "': the checkpoint was trained with " + value.dump() +
                                   ", the resumed run asks for " + b.at(key).dump());
  }
}

// A random start (loadModel's "random:" specs) gives every weight variance 1/fan_in, so the heads'
// raw outputs have norm ~10 and exp depth mode turns them into points e^10 away: the first
// updates are then spent on overflowing losses. Scaled down, the output layers start every point
// near the scene origin with confidence ~2, as a trained-from-scratch network should.
void shrinkOutputLayers(FastForwardModel& model) {
  at::NoGradGuard no_grad;
  const ParameterTable table = model.parameterTable();
  for (const ParameterTable::Entry& entry : table.entries()) {
    const bool output_layer = entry.name.rfind("downstream_head1.dpt.head.4.", 0) == 0 || entry.name.rfind("map_head.", 0) == 0;
    if (output_layer) entry.tensor->mul_(0.01);
  }
}

// Every query pixel of the preprocessed grid with its predicted point, back in the world frame.
Correspondences worldCorrespondences(const FastForwardPrediction& prediction, const SceneNormalization& normalization) {
  const at::Tensor points = prediction.query.pts3d[0].to(at::kDouble).contiguous();  // (H, W, 3)
  const at::Tensor confidence = prediction.query.conf[0].to(at::kFloat).contiguous();
  const int64_t height = points.size(0), width = points.size(1);
  const double* xyz = points.data_ptr<double>();
  const float* conf = confidence.data_ptr<float>();
  Correspondences out;
  out.reserve(static_cast<size_t>(height * width));
  for (int64_t y = 0; y < height; ++y) {
    for (int64_t x = 0; x < width; ++x) {
      const int64_t i = y * width + x;
      const Eigen::Vector3d point(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
      if (!point.allFinite() || !std::isfinite(conf[i])) continue;
      out.add(Eigen::Vector2d(static_cast<double>(x), static_cast<double>(y)), normalization.toWorld(point), conf[i]);
    }
  }
  return out;
}

// Infinite values (failed poses) sort last; the median of an empty list is infinite.
double median(std::vector<double> values) {
  if (values.empty()) return std::numeric_limits<double>::infinity();
  const size_t middle = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(middle), values.end());
  return values[middle];
}

}  // namespace

SampleOptions sampleOptions(const TrainingConfig& config, int patch_size) {
  SampleOptions options;
  options.mapping_frames = config.mapping_frames;
  options.min_map_tokens = config.min_map_tokens;
  options.max_map_tokens = config.max_map_tokens;
  options.min_overlap = config.min_overlap;
  options.max_overlap = config.max_overlap;
  options.overlap_candidates = config.overlap_candidates;
  options.overlap_stride = config.overlap_stride;
  options.long_side = config.long_side;
  options.patch_size = patch_size;
  options.colour_jitter = config.colour_jitter;
  return options;
}

uint64_t trainingSampleSeed(uint64_t run_seed, int64_t step) {
  return splitMix(splitMix(run_seed ^ 0x747261696e000000ULL) + static_cast<uint64_t>(step));
}

uint64_t validationSampleSeed(uint64_t run_seed, int64_t index) {
  return splitMix(splitMix(run_seed ^ 0x76616c6964000000ULL) + static_cast<uint64_t>(index));
}

struct Trainer::Losses {
  at::Tensor total;
  ConfidenceLossTerm query, map;
  double scale = 1;
  int64_t map_tokens = 0;
};

Trainer::Trainer(const TrainingConfig& config, std::vector<Scene> scenes, const std::filesystem::path& run_dir,
                 bool resume, std::vector<Scene> validation_scenes)
    : config_(config), run_dir_(run_dir) {
  config_.validate();
  setTorchThreadCount(config_.threads);
  device_ = config_.device == "cuda" ? at::Device(at::kCUDA) : at::Device(at::kCPU);
  if (config_.precision == "bf16" && device_.is_cpu()) {
    warnIfBfloat16IsEmulated("train with precision fp32 (docs/training.md)");
  }

  std::optional<CheckpointInfo> checkpoint;
  if (resume) {
    checkpoint = latestTrainingCheckpoint(run_dir_);
    if (!checkpoint) throwInputError((run_dir_ / "checkpoints" / "latest").string(), 0, "no checkpoint to resume from");
    checkResumable(checkpoint->config, config_, (checkpoint->folder / "model.safetensors").string());
  }
  ModelLoadOptions load;
  load.init_seed = config_.model_seed;
  LoadedModel loaded = loadModel(checkpoint ? (checkpoint->folder / "model.safetensors").string() : config_.model, load);
  model_ = std::move(loaded.model);
  model_description_ = loaded.description;
  if (!checkpoint && config_.model.rfind("random:", 0) == 0) shrinkOutputLayers(*model_);
  model_->to(device_, at::kFloat);

  auto trainable = trainableParameters(*model_, config_.train_encoder);
  for (auto& entry : trainable) entry.second.requires_grad_(true);
  AdamWOptions adam;
  adam.beta1 = config_.beta1;
  adam.beta2 = config_.beta2;
  adam.epsilon = config_.adam_epsilon;
  adam.weight_decay = config_.weight_decay;
  optimizer_ = std::make_unique<AdamW>(std::move(trainable), adam);
  if (checkpoint) loadOptimizerState(*checkpoint, *optimizer_);

  const SampleOptions samples = sampleOptions(config_, static_cast<int>(model_->config().dust3r.patch_size));
  sampler_ = std::make_unique<TrainingSampler>(std::move(scenes), samples);
  if (!validation_scenes.empty()) {
    SampleOptions validation = samples;
    validation.colour_jitter = 0;
    validation_sampler_ = std::make_unique<TrainingSampler>(std::move(validation_scenes), validation);
  }
}

int64_t Trainer::trainableParameterCount() const {
  int64_t count = 0;
  for (const auto& entry : optimizer_->parameters()) count += entry.second.numel();
  return count;
}

FastForwardPrediction Trainer::predict(const TrainingSample& sample) const {
  const AutocastGuard mixed_precision(device_.type(), at::kBFloat16, config_.precision == "bf16");
  // A frozen encoder records no graph: its tokens are constants for the decoder's backward.
  const auto encode = [&](const at::Tensor& image) {
    if (config_.train_encoder) return model_->encode(image);
    at::NoGradGuard frozen;
    return model_->encode(image);
  };
  const Dust3rEncoding query = encode(sample.query_image);
  std::vector<Dust3rEncoding> mapping;
  for (const at::Tensor& image : sample.mapping_images) mapping.push_back(encode(image));
  const MapTokens map = gatherMapTokens(mapping, sample.mapping_rays, sample.map_indices);
  return model_->forward(query, map);
}

Trainer::Losses Trainer::evaluate(const TrainingSample& sample) const { return lossesOf(predict(sample), sample); }

Trainer::Losses Trainer::lossesOf(const FastForwardPrediction& prediction, const TrainingSample& sample) const {
  Losses losses;
  losses.query = confidenceLoss(prediction.query.pts3d, prediction.query.conf, sample.query_points,
                                sample.query_valid, config_.alpha);
  losses.map = confidenceLoss(prediction.map.pts3d, prediction.map.conf, sample.map_points, sample.map_valid,
                              config_.alpha);
  losses.total = losses.query.loss + losses.map.loss;
  losses.scale = sample.normalization.scale;
  losses.map_tokens = sample.map_indices.size(0);
  return losses;
}

TrainingStepStats Trainer::step() { return step(sampler_->sample(trainingSampleSeed(config_.seed, stepsDone()))); }

TrainingStepStats Trainer::step(const TrainingSample& sample) {
  const int64_t index = stepsDone();
  const Losses losses = evaluate(sample);
  losses.total.backward();
  TrainingStepStats stats;
  stats.grad_norm = clipGradientNorm(optimizer_->parameters(), config_.clip_grad_norm);
  stats.learning_rate =
      cosineLearningRate(index, config_.steps, config_.warmup_steps, config_.learning_rate, config_.min_learning_rate);
  optimizer_->step(stats.learning_rate);
  stats.step = stepsDone();
  stats.loss = losses.total.item<double>();
  stats.query_loss = losses.query.loss.item<double>();
  stats.map_loss = losses.map.loss.item<double>();
  stats.query_error = losses.query.error.item<double>() * losses.scale;
  stats.map_error = losses.map.error.item<double>() * losses.scale;
  stats.map_tokens = losses.map_tokens;
  return stats;
}

ValidationStats Trainer::validate() {
  at::NoGradGuard no_grad;
  TrainingSampler& sampler = validation_sampler_ ? *validation_sampler_ : *sampler_;
  ValidationStats stats;
  std::vector<double> translation_errors, rotation_errors;
  for (int i = 0; i < config_.validation_samples; ++i) {
    const TrainingSample sample = sampler.sample(validationSampleSeed(config_.seed, i));
    const FastForwardPrediction prediction = predict(sample);
    const Losses losses = lossesOf(prediction, sample);
    stats.loss += losses.total.item<double>();
    stats.query_error += losses.query.error.item<double>() * losses.scale;
    stats.map_error += losses.map.error.item<double>() * losses.scale;
    ++stats.samples;

    const PnpResult pnp = estimatePose(worldCorrespondences(prediction, sample.normalization), sample.query_camera);
    const bool solved = pnp.status == PnpStatus::kSuccess;
    const double infinity = std::numeric_limits<double>::infinity();
    const double t = solved ? translationError(pnp.camera_to_world, sample.query_pose) : infinity;
    const double r = solved ? rotationErrorDeg(pnp.camera_to_world, sample.query_pose) : infinity;
    translation_errors.push_back(t);
    rotation_errors.push_back(r);
    stats.within_10cm_10deg += (t <= 0.10 && r <= 10.0) ? 1 : 0;
    stats.within_25cm_5deg += (t <= 0.25 && r <= 5.0) ? 1 : 0;
  }
  stats.loss /= stats.samples;
  stats.query_error /= stats.samples;
  stats.map_error /= stats.samples;
  stats.within_10cm_10deg /= stats.samples;
  stats.within_25cm_5deg /= stats.samples;
  stats.median_translation_error = median(translation_errors);
  stats.median_rotation_error_deg = median(rotation_errors);
  return stats;
}

std::filesystem::path Trainer::saveCheckpoint() {
  return writeTrainingCheckpoint(run_dir_, *model_, *optimizer_, config_, config_.keep_checkpoints);
}

}  // namespace ffloc
