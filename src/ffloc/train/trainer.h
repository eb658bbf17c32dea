#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "ffloc/data/scene.h"
#include "ffloc/model/fastforward_model.h"
#include "ffloc/train/adamw.h"
#include "ffloc/train/sample_prefetcher.h"
#include "ffloc/train/trainable_parameters.h"
#include "ffloc/train/training_config.h"
#include "ffloc/train/training_sample.h"

namespace ffloc {

struct TrainingStepStats {
  int64_t step = 0;  // 1-based: the number of updates done after this one
  // Means over the step's global batch (every rank's samples).
  double loss = 0, query_loss = 0, map_loss = 0;
  // The matching head's cross-entropy and the share of patches whose best token is the target
  // (matching_loss.h); 0 for a DPT head.
  double match_loss = 0, match_accuracy = 0;
  // Mean ||X - Xgt|| times the sample's scene scale s: metres on metric data.
  double query_error = 0, map_error = 0;
  double learning_rate = 0;
  double grad_norm = 0;  // before clipping
  int64_t map_tokens = 0;
  int64_t samples = 0;             // the global batch
  // This rank's time: the whole step, and in it the wait for samples not prepared in time, the
  // all-reduce of gradients and losses, and clipping with the optimiser update.
  double step_seconds = 0;
  double data_wait_seconds = 0;
  double allreduce_seconds = 0;
  double optimizer_seconds = 0;
  bool stop_requested = false;     // some rank called requestStop() before this step's update
};

// Validation on fixed samples: the losses, and the query's pose from its predicted points through
// the same confidence filter and PnP-RANSAC as localisation (pose errors in metres on metric data;
// a failed PnP counts as an infinite error).
struct ValidationStats {
  double loss = 0, query_error = 0, map_error = 0;  // means over the samples
  double match_loss = 0, match_accuracy = 0;
  double median_translation_error = 0;              // of the PnP poses
  double median_rotation_error_deg = 0;
  double within_10cm_10deg = 0;  // fraction of samples
  double within_25cm_5deg = 0;
  int samples = 0;
};

// Sums over some samples of what TrainingStepStats reports as means.
struct BatchLosses {
  double loss = 0, query_loss = 0, map_loss = 0, match_loss = 0, match_accuracy = 0, query_error = 0, map_error = 0;
  int64_t samples = 0;
};

// SampleOptions of a training config for a model with `patch_size`.
SampleOptions sampleOptions(const TrainingConfig& config, int patch_size);

// Seeds as pure functions of the run's settings, so resuming at step n replays exactly what step n
// would have drawn, on any number of ranks: sample `index` (0-based within the global batch) of
// training step `step` (0-based), the map token count that step's samples share, and validation
// sample `index`.
uint64_t trainingSampleSeed(uint64_t run_seed, int64_t step, int64_t index);
uint64_t stepTokenCountSeed(uint64_t run_seed, int64_t step);
uint64_t validationSampleSeed(uint64_t validation_seed, int64_t index);

class DataParallel;

// The training loop's state: model, optimiser, sampler and step count (paper Eq. 2, appendix), on
// one rank of a data-parallel run or on its own. A step takes config.batch_size x
// config.accumulate samples on each of the world's ranks; rank r's forward pass a holds the global
// batch's samples (a * world + r) * batch_size + [0, batch_size). Gradients are averaged over the
// global batch, so the run is the same however it is split. Float32 weights and optimiser;
// checkpoints in <run_dir>/checkpoints (training_checkpoint.h), written by rank 0.
class Trainer {
 public:
  // A fresh run from config.model, or, when `resume`, the latest checkpoint in run_dir (whose
  // stored configuration must agree with `config` on everything but the step count, the batch
  // split, the loader, and the logging, checkpoint and validation intervals; the global batch must
  // stay the same, and `steps` may not fall below the checkpoint's step; InputError naming the
  // field otherwise). `validation_scenes`: held-out scenes
  // for validate(); none: validation draws from the training scenes. `parallel`: this rank's
  // process group (not owned), or null for a run of one process.
  Trainer(const TrainingConfig& config, std::vector<Scene> scenes, const std::filesystem::path& run_dir,
          bool resume = false, std::vector<Scene> validation_scenes = {}, DataParallel* parallel = nullptr);
  ~Trainer();

  // One update on this rank's share of the current step's global batch. A run that diverges
  // stops with an InputError naming the step and the settings to try: a non-finite loss or
  // gradient norm before the update, non-finite parameters after it.
  TrainingStepStats step();
  // One update on exactly these samples, as the whole batch of a run of one process (overfitting
  // checks, custom data pipelines); the step count and the schedule advance as for step().
  TrainingStepStats step(const std::vector<TrainingSample>& samples);
  // Forward and backward passes of `samples` (one pass per query image size), adding `weight`
  // times the gradient of their summed loss to the parameters' gradients. Returns the sums.
  BatchLosses accumulateGradients(const std::vector<TrainingSample>& samples, double weight);
  // Ends the run after the next step on every rank (its stats say stop_requested), so that ranks
  // whose clocks disagree about a time budget still stop at the same step.
  void requestStop() { stop_requested_ = true; }
  // The sample validate() uses as its `index`-th.
  TrainingSample validationSample(int index);
  // config.validation_samples fixed samples (validationSampleSeed), without gradients; a
  // progress bar unless `quiet` (100000 samples ran half an hour in silence). Stops early when
  // `keep_going` says no before a sample (a time budget, a signal): `samples` then tells how many
  // were scored.
  ValidationStats validate(bool quiet = true, const std::function<bool()>& keep_going = {});
  // Rank 0 writes <run_dir>/checkpoints/step_<n>/ and points `latest` at it, keeping the newest
  // config.keep_checkpoints; other ranks write nothing. Returns the folder.
  std::filesystem::path saveCheckpoint();

  int64_t stepsDone() const { return optimizer_->stepCount(); }
  int64_t globalBatch() const;
  const TrainingConfig& config() const { return config_; }
  FastForwardModel& model() { return *model_; }
  AdamW& optimizer() { return *optimizer_; }
  const std::string& modelDescription() const { return model_description_; }
  // The image size the model given to start from had learned (its 'input_long_side'), which the
  // run replaces with the config's long_side.
  int64_t initialInputLongSide() const { return initial_input_long_side_; }
  int64_t trainableParameterCount() const;

 private:
  struct Losses;
  std::vector<FastForwardPrediction> predict(const std::vector<TrainingSample>& samples) const;
  Losses lossesOf(const FastForwardPrediction& prediction, const TrainingSample& sample) const;
  TrainingStepStats update(BatchLosses sums);
  TrainingSample drawTrainingSample(int64_t ordinal);

  TrainingConfig config_;
  std::filesystem::path run_dir_;
  DataParallel* parallel_ = nullptr;
  int rank_ = 0, world_size_ = 1;
  std::unique_ptr<FastForwardModel> model_;
  std::string model_description_;
  int64_t initial_input_long_side_ = 0;
  std::unique_ptr<AdamW> optimizer_;
  std::unique_ptr<TrainingSampler> sampler_;
  std::unique_ptr<TrainingSampler> validation_sampler_;  // null: validate on sampler_
  int64_t prefetch_start_step_ = 0;
  bool stop_requested_ = false;
  std::unique_ptr<SamplePrefetcher> prefetcher_;  // made by the first step()
  at::Device device_ = at::kCPU;
};

}  // namespace ffloc
