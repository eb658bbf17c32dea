#pragma once

#include <c10/core/ScalarType.h>

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "ffloc/model/fastforward_model.h"
#include "ffloc/model/parameter_table.h"

namespace ffloc {

// Where a FastForward model comes from, as the CLI's --model names it:
// - a FastForward checkpoint (safetensors or .pth holding map_head.* and ray_embed.*);
// - a DUSt3R checkpoint (.pth or safetensors): FastForward is initialised from it
//   (FastForwardModel::initializeFromDust3r), so its ray MLP and map head are untrained;
// - "default": the model shipped in models/ (models/MODEL_CARD.md), or the file named by the
//   FFLOC_MODEL environment variable when it is set;
// - "random:<preset>[:<seed>]" (preset "tiny", "small" or "large"): every parameter drawn from a seeded
//   generator, for tests and timing. Its predictions are meaningless.
struct ModelLoadOptions {
  // kFloat, or kBFloat16 for the backbone and the DPT head (whose last projection and the
  // post-processing stay float32; the map head too).
  at::ScalarType dtype = at::kFloat;
  uint64_t init_seed = 0;                      // the untrained layers of a DUSt3R initialisation
};

struct LoadedModel {
  std::unique_ptr<FastForwardModel> model;
  // Identity of the model, stored in every map so a map is only used with the model that
  // encoded it: "<origin>/<sizes>/<fingerprint of the float32 parameters and the architecture,
  // preprocessing included>". The fingerprint is of values, not files, so a .pth and its
  // safetensors conversion give the same id.
  std::string id;
  std::string description;  // one line for logs
};

// The `format` metadata of a training checkpoint's optimizer state (train/training_checkpoint.h),
// which loadModel names when it is given one.
inline constexpr char kTrainingStateFormat[] = "ffloc-train-state";

// A training run keeps its checkpoints in <run>/checkpoints/step_<n>/ and names the newest complete
// one in the one-line file <run>/checkpoints/latest (train/training_checkpoint.h). `--model` reads
// the weights of the folder it names as the trainer resumes from it. Returns that line, "" when
// the file cannot be read.
std::string readLatestCheckpointName(const std::filesystem::path& latest_file);
// Whether `name`, read from a `latest` file, names a step folder beside it.
bool isCheckpointFolderName(const std::string& name);

// The file "default" stands for.
std::string defaultModelPath();

// What keeps `spec` from naming a model, found without reading any weights ("" when nothing):
// an unknown random preset or seed, a missing default model, a path that is not a file.
std::string modelSpecProblem(const std::string& spec);

// InputError naming the file (or the spec) when it cannot be read or is neither kind of checkpoint,
// and naming the tensor when a file that carries checksums (saveModel's) no longer matches them.
LoadedModel loadModel(const std::string& spec, const ModelLoadOptions& options = {});

// Writes every parameter as float32 safetensors (atomically) with the model's architecture and
// input size in the metadata, and checksums of both, so that loadModel reads it back as the same
// model or refuses it damaged; `metadata` adds entries (a training checkpoint's step and settings).
void saveModel(FastForwardModel& model, const std::filesystem::path& path,
               std::map<std::string, std::string> metadata = {});

// Fills every parameter of `model` from `seed`: LayerNorm weights near 1, biases near 0, other
// weights uniform with variance 1/fan_in, so activations stay O(1) through the network.
void randomizeParameters(FastForwardModel& model, uint64_t seed);
// The same values for any parameter table (a DUSt3R model too), each tensor cast to `dtype` as it
// is drawn; `ffloc bench model` times models filled this way.
void randomizeParameters(const ParameterTable& table, uint64_t seed, at::ScalarType dtype);

// 64-bit fingerprint of every parameter (name and float32 values, in state_dict order).
uint64_t parameterFingerprint(FastForwardModel& model);

}  // namespace ffloc
