#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "ffloc/data/scene.h"
#include "ffloc/model/fastforward_model.h"
#include "ffloc/train/adamw.h"
#include "ffloc/train/trainable_parameters.h"
#include "ffloc/train/training_config.h"
#include "ffloc/train/training_sample.h"

namespace ffloc {

struct TrainingStepStats {
  int64_t step = 0;  // 1-based: the number of updates done after this one
  double loss = 0, query_loss = 0, map_loss = 0;
  // Mean ||X - Xgt|| times the sample's scene scale s: metres on metric data.
  double query_error = 0, map_error = 0;
  double learning_rate = 0;
  double grad_norm = 0;  // before clipping
  int64_t map_tokens = 0;
};

// Validation on fixed samples: the losses, and the query's pose from its predicted points through
// the same confidence filter and PnP-RANSAC as localisation (pose errors in metres on metric data;
// a failed PnP counts as an infinite error).
struct ValidationStats {
  double loss = 0, query_error = 0, map_error = 0;  // means over the samples
  double median_translation_error = 0;              // of the PnP poses
  double median_rotation_error_deg = 0;
  double within_10cm_10deg = 0;  // fraction of samples
  double within_25cm_5deg = 0;
  int samples = 0;
};

// SampleOptions of a training config for a model with `patch_size`.
SampleOptions sampleOptions(const TrainingConfig& config, int patch_size);

// The seed of the sample of training step `step` (0-based), or of validation sample `index`:
// a pure function of the run seed, so resuming at step n replays exactly what step n would have
// drawn.
uint64_t trainingSampleSeed(uint64_t run_seed, int64_t step);
uint64_t validationSampleSeed(uint64_t run_seed, int64_t index);

// The training loop's state: model, optimiser, sampler and step count (paper Eq. 2, appendix).
// Single-sample steps in float32; checkpoints in <run_dir>/checkpoints (training_checkpoint.h).
class Trainer {
 public:
  // A fresh run from config.model, or, when `resume`, the latest checkpoint in run_dir (whose
  // stored configuration must agree with `config` on everything but the step count and the
  // logging, checkpoint and validation intervals; InputError naming the field otherwise).
  // `validation_scenes`: held-out scenes for validate(); none: validation draws from the training
  // scenes.
  Trainer(const TrainingConfig& config, std::vector<Scene> scenes, const std::filesystem::path& run_dir,
          bool resume = false, std::vector<Scene> validation_scenes = {});

  // One update on the sample of the current step (trainingSampleSeed).
  TrainingStepStats step();
  // One update on a given sample (overfitting checks, custom data pipelines); the step counts
  // and the schedule advance as for step().
  TrainingStepStats step(const TrainingSample& sample);
  TrainingSampler& sampler() { return *sampler_; }
  // config.validation_samples fixed samples (validationSampleSeed), without gradients.
  ValidationStats validate();
  // Writes <run_dir>/checkpoints/step_<n>/ and points `latest` at it; keeps the newest
  // config.keep_checkpoints. Returns the folder.
  std::filesystem::path saveCheckpoint();

  int64_t stepsDone() const { return optimizer_->stepCount(); }
  const TrainingConfig& config() const { return config_; }
  FastForwardModel& model() { return *model_; }
  const std::string& modelDescription() const { return model_description_; }
  int64_t trainableParameterCount() const;

 private:
  struct Losses;
  Losses evaluate(const TrainingSample& sample) const;
  FastForwardPrediction predict(const TrainingSample& sample) const;
  Losses lossesOf(const FastForwardPrediction& prediction, const TrainingSample& sample) const;

  TrainingConfig config_;
  std::filesystem::path run_dir_;
  std::unique_ptr<FastForwardModel> model_;
  std::string model_description_;
  std::unique_ptr<AdamW> optimizer_;
  std::unique_ptr<TrainingSampler> sampler_;
  std::unique_ptr<TrainingSampler> validation_sampler_;  // null: validate on sampler_
  at::Device device_ = at::kCPU;
};

}  // namespace ffloc
