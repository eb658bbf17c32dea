#include "ffloc/train/trainer.h"

#include <ATen/TensorOperators.h>
#include <ATen/ops/cat.h>
#include <ATen/ops/isfinite.h>
#include <ATen/ops/tensor.h>
#include <c10/core/GradMode.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <set>

#include "ffloc/core/clock.h"
#include "ffloc/core/cpu_features.h"
#include "ffloc/core/error.h"
#include "ffloc/core/progress.h"
#include "ffloc/core/random.h"
#include "ffloc/core/statistics.h"
#include "ffloc/model/torch_threads.h"
#include "ffloc/model/model_loader.h"
#include "ffloc/pose/pnp.h"
#include "ffloc/train/autocast.h"
#include "ffloc/train/confidence_loss.h"
#include "ffloc/train/data_parallel.h"
#include "ffloc/train/matching_loss.h"
#include "ffloc/train/training_checkpoint.h"

namespace ffloc {

namespace {

// Settings that may change between a run and its resumption: they do not alter what the
// optimiser sees (the step count changes the schedule's length, which is the user's call).
const std::set<std::string>& resumableFields() {
  static const std::set<std::string> fields = {
      "steps",      "log_every", "checkpoint_every", "keep_checkpoints", "validation_every", "validation_samples",
      "threads",    "device",    "precision",        "batch_size",       "accumulate",       "loader_threads",
      "prefetch_samples"};
  return fields;
}

int64_t globalBatchOf(const TrainingConfig& config, int world_size) {
  return static_cast<int64_t>(config.batch_size) * config.accumulate * world_size;
}

void checkResumable(const CheckpointInfo& stored, const TrainingConfig& requested, int world_size,
                    const std::string& origin) {
  const nlohmann::json a = toJson(stored.config), b = toJson(requested);
  if (const std::optional<std::string> key = firstDifferingField(a, b, resumableFields()))
    throwInputError(origin, 0, "field '" + *key + "': the checkpoint was trained with " + a.at(*key).dump() +
                                   ", the resumed run asks for " + b.at(*key).dump());
  const int64_t before = globalBatchOf(stored.config, stored.world_size), now = globalBatchOf(requested, world_size);
  if (before != now) {
    throwInputError(origin, 0, "field 'batch_size': the checkpoint was trained with a global batch of " +
                                   std::to_string(before) + " (batch_size x accumulate x " +
                                   std::to_string(stored.world_size) + " ranks), the resumed run asks for " +
                                   std::to_string(now));
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

// std::to_string says "-nan" for some NaNs.
std::string nonFiniteName(double value) {
  if (std::isnan(value)) return "nan";
  return value > 0 ? "inf" : "-inf";
}

// A run whose loss, gradients or weights went non-finite at `step` (1-based): `what` says which.
[[noreturn]] void throwDiverged(int64_t step, const std::string& what, const TrainingConfig& config) {
  char remedy[256];
  std::snprintf(remedy, sizeof(remedy),
                "try a lower learning_rate (now %g), a longer warmup_steps (now %lld) or clip_grad_norm (now %g%s)",
                config.learning_rate, static_cast<long long>(config.warmup_steps), config.clip_grad_norm,
                config.clip_grad_norm > 0 ? "" : ", off");
  throw InputError("training step " + std::to_string(step) + ": " + what +
                   ": the run diverged and stops here, without a checkpoint of this state; " + remedy);
}

// One reduction read back, not one per tensor: on a GPU each read waits for the device.
int64_t nonFiniteCount(const std::vector<std::pair<std::string, at::Tensor>>& parameters) {
  at::NoGradGuard no_grad;
  int64_t elements = 0;
  at::Tensor finite;
  for (const auto& entry : parameters) {
    elements += entry.second.numel();
    const at::Tensor here = at::isfinite(entry.second).sum();
    finite = finite.defined() ? finite + here : here;
  }
  return finite.defined() ? elements - finite.item<int64_t>() : 0;
}

// Failed poses count as infinite errors; with no sample the median is infinite.
double medianError(const std::vector<double>& errors) {
  return errors.empty() ? std::numeric_limits<double>::infinity() : median(errors);
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

uint64_t trainingSampleSeed(uint64_t run_seed, int64_t step, int64_t index) {
  return mix64(mix64(mix64(run_seed ^ 0x747261696e000000ULL) + static_cast<uint64_t>(step)) + static_cast<uint64_t>(index));
}

uint64_t stepTokenCountSeed(uint64_t run_seed, int64_t step) {
  return mix64(mix64(run_seed ^ 0x746f6b656e000000ULL) + static_cast<uint64_t>(step));
}

uint64_t validationSampleSeed(uint64_t validation_seed, int64_t index) {
  return mix64(mix64(validation_seed ^ 0x76616c6964000000ULL) + static_cast<uint64_t>(index));
}

struct Trainer::Losses {
  ConfidenceLossTerm query, map;
  MatchingLossTerm match;  // the matching head's; loss undefined for a DPT head
  at::Tensor total;
  double scale = 1;
};

Trainer::Trainer(const TrainingConfig& config, std::vector<Scene> scenes, const std::filesystem::path& run_dir,
                 bool resume, std::vector<Scene> validation_scenes, DataParallel* parallel)
    : config_(config), run_dir_(run_dir), parallel_(parallel) {
  config_.validate();
  if (parallel_) {
    rank_ = parallel_->environment().rank;
    world_size_ = parallel_->environment().world_size;
  }
  setTorchThreadCount(config_.threads);
  device_ = config_.device == "cuda" ? at::Device(at::kCUDA, static_cast<c10::DeviceIndex>(
                                                                 parallel_ ? parallel_->environment().local_rank : 0))
                                     : at::Device(at::kCPU);
  if (config_.precision == "bf16" && device_.is_cpu()) {
    warnIfBfloat16IsEmulated("train with precision fp32 (docs/training.md)");
  }

  std::optional<CheckpointInfo> checkpoint;
  if (resume) {
    checkpoint = latestTrainingCheckpoint(run_dir_);
    if (!checkpoint) throwInputError((run_dir_ / "checkpoints" / "latest").string(), 0, "no checkpoint to resume from");
    checkResumable(*checkpoint, config_, world_size_, (checkpoint->folder / "model.safetensors").string());
    if (const auto problem = resumeProblem(*checkpoint, config_))
      throw TrainingConfigError("training config", *problem);
  }
  ModelLoadOptions load;
  load.init_seed = config_.model_seed;
  LoadedModel loaded = loadModel(checkpoint ? (checkpoint->folder / "model.safetensors").string() : config_.model, load);
  model_ = std::move(loaded.model);
  model_description_ = loaded.description;
  // The model learns at the training images' size; its checkpoints record that size.
  initial_input_long_side_ = model_->config().input_long_side;
  model_->setInputLongSide(config_.long_side);
  if (!checkpoint && config_.model.rfind("random:", 0) == 0) shrinkOutputLayers(*model_);
  model_->to(device_, at::kFloat);

  auto trainable = trainableParameters(*model_, config_.train_encoder, config_.trained_parameters);
  for (auto& entry : trainable) entry.second.requires_grad_(true);
  AdamWOptions adam;
  adam.beta1 = config_.beta1;
  adam.beta2 = config_.beta2;
  adam.epsilon = config_.adam_epsilon;
  adam.weight_decay = config_.weight_decay;
  optimizer_ = std::make_unique<AdamW>(std::move(trainable), adam);
  if (checkpoint) loadOptimizerState(*checkpoint, *optimizer_);
  if (parallel_) {
    // Every rank starts from rank 0's weights and moments, whatever each loaded.
    at::NoGradGuard no_grad;
    std::vector<at::Tensor> state;
    for (const auto& entry : optimizer_->parameters()) state.push_back(entry.second);
    for (const auto& entry : optimizer_->state()) state.push_back(entry.second);
    parallel_->broadcastFromRankZero(state);
  }

  const SampleOptions samples = sampleOptions(config_, static_cast<int>(model_->config().dust3r.patch_size));
  sampler_ = std::make_unique<TrainingSampler>(std::move(scenes), samples);
  if (!validation_scenes.empty()) {
    SampleOptions validation = samples;
    validation.colour_jitter = 0;
    validation_sampler_ = std::make_unique<TrainingSampler>(std::move(validation_scenes), validation, "validation data");
    // Drawn once now: validation data where no sample can be drawn was refused only at the first
    // validation, validation_every steps in (found by an outside probe).
    if (config_.validation_every > 0) validationSample(0);
  }
}

Trainer::~Trainer() = default;

int64_t Trainer::trainableParameterCount() const {
  int64_t count = 0;
  for (const auto& entry : optimizer_->parameters()) count += entry.second.numel();
  return count;
}

int64_t Trainer::globalBatch() const { return globalBatchOf(config_, world_size_); }

std::vector<FastForwardPrediction> Trainer::predict(const std::vector<TrainingSample>& samples) const {
  const AutocastGuard mixed_precision(device_.type(), at::kBFloat16, config_.precision == "bf16");
  // A frozen encoder records no graph: its tokens are constants for the decoder's backward.
  const auto encode = [&](const at::Tensor& images) {
    if (config_.train_encoder) return model_->encode(images);
    at::NoGradGuard frozen;
    return model_->encode(images);
  };
  const auto sizeOf = [](const at::Tensor& image) { return std::make_pair(image.size(2), image.size(3)); };
  // Images of one size share an encoder pass: the mapping images of all samples, then the queries.
  std::map<std::pair<int64_t, int64_t>, std::vector<std::pair<size_t, size_t>>> mapping_by_size;
  for (size_t s = 0; s < samples.size(); ++s) {
    for (size_t k = 0; k < samples[s].mapping_images.size(); ++k) {
      mapping_by_size[sizeOf(samples[s].mapping_images[k])].emplace_back(s, k);
    }
  }
  std::vector<std::vector<Dust3rEncoding>> mapping(samples.size());
  for (size_t s = 0; s < samples.size(); ++s) mapping[s].resize(samples[s].mapping_images.size());
  for (const auto& [size, members] : mapping_by_size) {
    std::vector<at::Tensor> images;
    for (const auto& [s, k] : members) images.push_back(samples[s].mapping_images[k].to(device_));
    const Dust3rEncoding encoded = encode(at::cat(images, 0));
    for (size_t i = 0; i < members.size(); ++i) {
      Dust3rEncoding& one = mapping[members[i].first][members[i].second];
      one.tokens = encoded.tokens.narrow(0, static_cast<int64_t>(i), 1);
      one.positions = encoded.positions.narrow(0, static_cast<int64_t>(i), 1);
      one.height = encoded.height;
      one.width = encoded.width;
    }
  }

  std::map<std::pair<int64_t, int64_t>, std::vector<size_t>> queries_by_size;
  for (size_t s = 0; s < samples.size(); ++s) queries_by_size[sizeOf(samples[s].query_image)].push_back(s);
  std::vector<FastForwardPrediction> out(samples.size());
  for (const auto& [size, members] : queries_by_size) {
    std::vector<at::Tensor> images;
    std::vector<MapTokens> maps;
    for (size_t s : members) {
      images.push_back(samples[s].query_image.to(device_));
      maps.push_back(assembleMapTokens(samples[s].layout, mapping[s]));
    }
    if (members.size() > 1 && maps.front().features.size(1) != maps.back().features.size(1)) {
      throw std::invalid_argument("Trainer: samples of one forward pass must share their map token count");
    }
    MapTokens map;
    const auto stack = [&](at::Tensor MapTokens::*field) {
      std::vector<at::Tensor> parts;
      for (const MapTokens& one : maps) parts.push_back(one.*field);
      return at::cat(parts, 0);
    };
    map.features = stack(&MapTokens::features);
    map.positions = stack(&MapTokens::positions);
    map.rays = stack(&MapTokens::rays);
    map.image_index = stack(&MapTokens::image_index);
    map.token_index = stack(&MapTokens::token_index);
    // Every sampled token's point, from the mapping frames' depth as a map built with depth has.
    std::vector<at::Tensor> points, point_valid;
    for (size_t s : members) {
      points.push_back(samples[s].map_points.to(device_));
      point_valid.push_back(samples[s].map_valid.to(device_));
    }
    map.points = at::cat(points, 0);
    map.point_valid = at::cat(point_valid, 0);
    const FastForwardPrediction batch = model_->forward(encode(at::cat(images, 0)), map);
    for (size_t i = 0; i < members.size(); ++i) {
      const int64_t row = static_cast<int64_t>(i);
      FastForwardPrediction& one = out[members[i]];
      one.query.pts3d = batch.query.pts3d.narrow(0, row, 1);
      one.query.conf = batch.query.conf.narrow(0, row, 1);
      one.map.pts3d = batch.map.pts3d.narrow(0, row, 1);
      one.map.conf = batch.map.conf.narrow(0, row, 1);
      if (batch.match_logits.defined()) one.match_logits = batch.match_logits.narrow(0, row, 1);
    }
  }
  return out;
}

Trainer::Losses Trainer::lossesOf(const FastForwardPrediction& prediction, const TrainingSample& sample) const {
  Losses losses;
  losses.map = confidenceLoss(prediction.map.pts3d, prediction.map.conf, sample.map_points, sample.map_valid, config_.alpha);
  losses.scale = sample.layout.normalization.scale;
  if (!prediction.match_logits.defined()) {
    losses.query = confidenceLoss(prediction.query.pts3d, prediction.query.conf, sample.query_points, sample.query_valid,
                                  config_.alpha);
    losses.total = losses.query.loss + losses.map.loss;
    return losses;
  }
  const int64_t patch = model_->config().dust3r.patch_size;
  const PatchGroundTruth truth = patchCentreGroundTruth(sample.query_points.to(device_), sample.query_valid.to(device_), patch);
  losses.query = confidenceLoss(prediction.query.pts3d, prediction.query.conf, truth.points, truth.valid, config_.alpha);
  // A token is the right match when its point lies within match_radius patch footprints of the
  // patch's true point; the footprint grows with the distance from the query camera.
  const at::Tensor points = truth.points.reshape({-1, 3}), valid = truth.valid.reshape({-1});
  const Eigen::Vector3d centre = sample.layout.normalization.normalize(sample.query_pose).t;
  const at::Tensor camera = at::tensor(std::vector<float>{static_cast<float>(centre.x()), static_cast<float>(centre.y()),
                                                          static_cast<float>(centre.z())})
                                .to(device_);
  const at::Tensor radius = (points - camera).norm(2, -1) *
                            (config_.match_radius * static_cast<double>(patch) / sample.query_camera.fx);
  const at::Tensor targets = matchingTargets(points, valid, sample.map_points[0].to(device_),
                                             sample.map_valid[0].to(device_), radius);
  losses.match = matchingLoss(prediction.match_logits[0], targets);
  // The map head's targets are the points its tokens already carry: logged, not trained on, so
  // that its large early errors do not dominate the clipped gradient.
  losses.total = config_.point_weight * losses.query.loss + config_.match_weight * losses.match.loss;
  return losses;
}

BatchLosses Trainer::accumulateGradients(const std::vector<TrainingSample>& samples, double weight) {
  BatchLosses sums;
  if (samples.empty()) return sums;
  const std::vector<FastForwardPrediction> predictions = predict(samples);
  std::vector<at::Tensor> totals;
  for (size_t i = 0; i < samples.size(); ++i) {
    const Losses losses = lossesOf(predictions[i], samples[i]);
    totals.push_back(losses.total);
    sums.loss += losses.total.item<double>();
    sums.query_loss += losses.query.loss.item<double>();
    sums.map_loss += losses.map.loss.item<double>();
    if (losses.match.loss.defined()) {
      sums.match_loss += losses.match.loss.item<double>();
      sums.match_accuracy += losses.match.accuracy;
    }
    sums.query_error += losses.query.error.item<double>() * losses.scale;
    sums.map_error += losses.map.error.item<double>() * losses.scale;
    ++sums.samples;
  }
  at::Tensor total = totals[0];
  for (size_t i = 1; i < totals.size(); ++i) total = total + totals[i];
  (total * weight).backward();
  return sums;
}

TrainingSample Trainer::drawTrainingSample(int64_t ordinal) {
  const int64_t per_step = static_cast<int64_t>(config_.batch_size) * config_.accumulate;
  const int64_t step = prefetch_start_step_ + ordinal / per_step;
  const int64_t position = ordinal % per_step;
  const int64_t pass = position / config_.batch_size, slot = position % config_.batch_size;
  const int64_t index = (pass * world_size_ + rank_) * config_.batch_size + slot;
  return sampler_->sample(trainingSampleSeed(config_.seed, step, index),
                          sampler_->mapTokenCount(stepTokenCountSeed(config_.seed, step)));
}

TrainingStepStats Trainer::step() {
  const auto start = std::chrono::steady_clock::now();
  if (!prefetcher_) {
    prefetch_start_step_ = stepsDone();
    prefetcher_ = std::make_unique<SamplePrefetcher>([this](int64_t ordinal) { return drawTrainingSample(ordinal); },
                                                     config_.loader_threads, config_.prefetch_samples);
  }
  const double waited_before = prefetcher_->waitedSeconds();
  BatchLosses sums;
  const double weight = 1.0 / static_cast<double>(globalBatch());
  for (int pass = 0; pass < config_.accumulate; ++pass) {
    std::vector<TrainingSample> samples;
    for (int i = 0; i < config_.batch_size; ++i) samples.push_back(prefetcher_->next());
    const BatchLosses pass_sums = accumulateGradients(samples, weight);
    sums.loss += pass_sums.loss;
    sums.query_loss += pass_sums.query_loss;
    sums.map_loss += pass_sums.map_loss;
    sums.query_error += pass_sums.query_error;
    sums.map_error += pass_sums.map_error;
    sums.match_loss += pass_sums.match_loss;
    sums.match_accuracy += pass_sums.match_accuracy;
    sums.samples += pass_sums.samples;
  }
  TrainingStepStats stats = update(sums);
  stats.data_wait_seconds = prefetcher_->waitedSeconds() - waited_before;
  stats.step_seconds = secondsSince(start);
  stats.map_tokens = sampler_->mapTokenCount(stepTokenCountSeed(config_.seed, stats.step - 1));
  return stats;
}

TrainingStepStats Trainer::step(const std::vector<TrainingSample>& samples) {
  if (parallel_) throw std::logic_error("Trainer::step(samples) is for a run of one process");
  const auto start = std::chrono::steady_clock::now();
  const BatchLosses sums = accumulateGradients(samples, 1.0 / static_cast<double>(samples.size()));
  TrainingStepStats stats = update(sums);
  stats.step_seconds = secondsSince(start);
  stats.map_tokens = samples.empty() ? 0 : samples[0].layout.indices.size(0);
  return stats;
}

TrainingStepStats Trainer::update(BatchLosses sums) {
  const int64_t index = stepsDone();
  TrainingStepStats stats;
  auto start = std::chrono::steady_clock::now();
  if (parallel_) {
    parallel_->allReduceSum(gradientsOf(optimizer_->parameters()));
    at::Tensor totals = at::tensor(std::vector<double>{sums.loss, sums.query_loss, sums.map_loss, sums.match_loss,
                                                       sums.match_accuracy, sums.query_error, sums.map_error,
                                                       static_cast<double>(sums.samples), stop_requested_ ? 1.0 : 0.0},
                                   at::TensorOptions().dtype(at::kDouble));
    parallel_->allReduceSum({totals});
    const double* reduced = totals.data_ptr<double>();
    sums = {reduced[0], reduced[1], reduced[2], reduced[3], reduced[4], reduced[5], reduced[6], static_cast<int64_t>(reduced[7])};
    stop_requested_ = reduced[8] > 0;
    stats.allreduce_seconds = secondsSince(start);
  }
  start = std::chrono::steady_clock::now();
  stats.grad_norm = clipGradientNorm(optimizer_->parameters(), config_.clip_grad_norm);
  // Every rank sees the same reduced loss, gradients and weights, so all of them stop here
  // together. Stopping before the update keeps the weights as the last step left them, and the
  // caller's checkpoints as they were: a run that carried on wrote NaN checkpoints and rotated the
  // good ones out.
  if (!std::isfinite(sums.loss)) throwDiverged(index + 1, "the loss is " + nonFiniteName(sums.loss), config_);
  if (!std::isfinite(stats.grad_norm)) {
    throwDiverged(index + 1, "the gradient norm is " + nonFiniteName(stats.grad_norm), config_);
  }
  stats.learning_rate =
      cosineLearningRate(index, config_.steps, config_.warmup_steps, config_.learning_rate, config_.min_learning_rate);
  optimizer_->step(stats.learning_rate);
  if (const int64_t broken = nonFiniteCount(optimizer_->parameters())) {
    throwDiverged(index + 1, std::to_string(broken) + " parameters are non-finite after the update", config_);
  }
  stats.optimizer_seconds = secondsSince(start);
  stats.step = stepsDone();
  const double count = static_cast<double>(std::max<int64_t>(sums.samples, 1));
  stats.loss = sums.loss / count;
  stats.query_loss = sums.query_loss / count;
  stats.map_loss = sums.map_loss / count;
  stats.match_loss = sums.match_loss / count;
  stats.match_accuracy = sums.match_accuracy / count;
  stats.query_error = sums.query_error / count;
  stats.map_error = sums.map_error / count;
  stats.samples = sums.samples;
  stats.stop_requested = stop_requested_;
  return stats;
}

TrainingSample Trainer::validationSample(int index) {
  TrainingSampler& sampler = validation_sampler_ ? *validation_sampler_ : *sampler_;
  const uint64_t seed = validationSampleSeed(config_.validation_seed, index);
  return sampler.sample(seed, sampler.mapTokenCount(mix64(seed)));
}

ValidationStats Trainer::validate(bool quiet, const std::function<bool()>& keep_going) {
  at::NoGradGuard no_grad;
  ValidationStats stats;
  std::vector<double> translation_errors, rotation_errors;
  ProgressBar progress("validating", static_cast<size_t>(config_.validation_samples), quiet);
  for (int i = 0; i < config_.validation_samples && (!keep_going || keep_going()); ++i) {
    progress.update(static_cast<size_t>(i));
    const TrainingSample sample = validationSample(i);
    const FastForwardPrediction prediction = predict({sample}).front();
    const Losses losses = lossesOf(prediction, sample);
    stats.loss += losses.total.item<double>();
    stats.query_error += losses.query.error.item<double>() * losses.scale;
    stats.map_error += losses.map.error.item<double>() * losses.scale;
    if (losses.match.loss.defined()) {
      stats.match_loss += losses.match.loss.item<double>();
      stats.match_accuracy += losses.match.accuracy;
    }
    ++stats.samples;

    const PnpResult pnp =
        estimatePose(queryCorrespondences(prediction.query, 0, sample.layout.normalization,
                                          model_->config().queryGridStride()),
                     sample.query_camera);
    const bool solved = pnp.status == PnpStatus::kSuccess;
    const double infinity = std::numeric_limits<double>::infinity();
    const double t = solved ? translationError(pnp.camera_to_world, sample.query_pose) : infinity;
    const double r = solved ? rotationErrorDeg(pnp.camera_to_world, sample.query_pose) : infinity;
    translation_errors.push_back(t);
    rotation_errors.push_back(r);
    stats.within_10cm_10deg += (t <= 0.10 && r <= 10.0) ? 1 : 0;
    stats.within_25cm_5deg += (t <= 0.25 && r <= 5.0) ? 1 : 0;
  }
  progress.finish(static_cast<size_t>(stats.samples));
  if (stats.samples == 0) return stats;
  stats.loss /= stats.samples;
  stats.query_error /= stats.samples;
  stats.map_error /= stats.samples;
  stats.match_loss /= stats.samples;
  stats.match_accuracy /= stats.samples;
  stats.within_10cm_10deg /= stats.samples;
  stats.within_25cm_5deg /= stats.samples;
  stats.median_translation_error = medianError(translation_errors);
  stats.median_rotation_error_deg = medianError(rotation_errors);
  return stats;
}

std::filesystem::path Trainer::saveCheckpoint() {
  if (rank_ != 0) return run_dir_ / "checkpoints";
  return writeTrainingCheckpoint(run_dir_, *model_, *optimizer_, config_, config_.keep_checkpoints, world_size_);
}

}  // namespace ffloc
