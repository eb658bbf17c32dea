#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>
#include <string>

#include "ffloc/model/fastforward_model.h"
#include "ffloc/train/adamw.h"
#include "ffloc/train/training_config.h"

namespace ffloc {

// A training checkpoint is a folder <run_dir>/checkpoints/step_<8 digits>/ with
// - model.safetensors: every FastForward parameter (float32), metadata format
//   "ffloc-fastforward", the step and the training config as JSON. Any `--model` option reads it.
// - optimizer.safetensors: AdamW's moments ("exp_avg.<name>", "exp_avg_sq.<name>"), metadata
//   format "ffloc-train-state", the step and the config.
// The folder is written under a temporary name and renamed, then <run_dir>/checkpoints/latest
// (one line: the folder name) is replaced atomically, so a crash at any point leaves the
// previous checkpoint intact and `latest` always names a complete one. Everything random in a
// run derives from (seed, step), so the step is the whole RNG and data-position state. Both files
// carry checksums of every tensor and of their metadata (io/tensor_checksums.h), verified on
// every read, so a damaged checkpoint is refused instead of resumed with other values;
// checkpoints written before them are read unchecked.
struct CheckpointInfo {
  std::filesystem::path folder;
  int64_t step = 0;
  TrainingConfig config;
  int world_size = 1;  // ranks of the run that wrote it: with config, its global batch
};

std::filesystem::path writeTrainingCheckpoint(const std::filesystem::path& run_dir, FastForwardModel& model,
                                              const AdamW& optimizer, const TrainingConfig& config,
                                              int keep_last, int world_size = 1);

// The checkpoint folders under <run_dir>/checkpoints (step_<n>, not the .partial or .replaced
// ones of a write under way), oldest first; empty when there are none.
std::vector<std::filesystem::path> trainingCheckpointFolders(const std::filesystem::path& run_dir);

// The checkpoint `latest` names; nullopt when run_dir has none. InputError naming the file for a
// broken `latest`, a missing folder or unreadable or damaged metadata.
std::optional<CheckpointInfo> latestTrainingCheckpoint(const std::filesystem::path& run_dir);

// What stops `config` from continuing the run whose latest checkpoint is `checkpoint` (field and
// message, as TrainingConfig::problem gives them): fewer steps than the run has done.
std::optional<TrainingConfigProblem> resumeProblem(const CheckpointInfo& checkpoint, const TrainingConfig& config);

// Restores AdamW's moments and step from a checkpoint folder (after the model weights were
// loaded from its model.safetensors); InputError naming the file and the tensor for a damaged one.
void loadOptimizerState(const CheckpointInfo& checkpoint, AdamW& optimizer);

}  // namespace ffloc
