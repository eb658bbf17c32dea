#include "ffloc/train/training_checkpoint.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <vector>

#include "ffloc/core/error.h"
#include "ffloc/io/json_fields.h"
#include "ffloc/io/tensor_checksums.h"
#include "ffloc/model/model_loader.h"
#include "ffloc/model/tensor_conversion.h"
#include "ffloc/model/torch_threads.h"

namespace ffloc {

namespace {

namespace fs = std::filesystem;

std::string folderName(int64_t step) {
  char name[32];
  std::snprintf(name, sizeof(name), "step_%08lld", static_cast<long long>(step));
  return name;
}

void writeTextAtomically(const fs::path& path, const std::string& text) {
  const fs::path temporary = path.string() + ".tmp";
  {
    std::ofstream out(temporary, std::ios::trunc);
    out << text;
    if (!out.flush()) throwInputError(temporary.string(), 0, "cannot write");
  }
  fs::rename(temporary, path);
}

const std::string& metadataField(const TensorArchive& archive, const std::string& key) {
  const auto found = archive.metadata().find(key);
  if (found == archive.metadata().end()) throwInputError(archive.path().string(), 0, "metadata '" + key + "': missing");
  return found->second;
}

int64_t parseCount(const TensorArchive& archive, const std::string& key, int64_t minimum) {
  const std::string& text = metadataField(archive, key);
  try {
    size_t used = 0;
    const long long value = std::stoll(text, &used);
    if (used != text.size() || value < minimum) throw std::invalid_argument(text);
    return value;
  } catch (const std::exception&) {
    throwInputError(archive.path().string(), 0, "metadata '" + key + "': not a count of at least " +
                                                     std::to_string(minimum) + ": '" + text + "'");
  }
}

// Whether a step's folder holds both files a resume reads.
bool isCompleteCheckpoint(const fs::path& folder) {
  return fs::exists(folder / "model.safetensors") && fs::exists(folder / "optimizer.safetensors");
}

// Keeps the newest `keep_last` complete checkpoint folders and `keep` whatever its age.
void pruneCheckpoints(const fs::path& run_dir, const fs::path& keep, int keep_last) {
  const std::vector<fs::path> existing = trainingCheckpointFolders(run_dir);
  for (size_t i = 0; i + static_cast<size_t>(keep_last) < existing.size(); ++i) {
    if (existing[i] != keep) fs::remove_all(existing[i]);
  }
}

}  // namespace

fs::path writeTrainingCheckpoint(const fs::path& run_dir, FastForwardModel& model, const AdamW& optimizer,
                                 const TrainingConfig& config, int keep_last, int world_size) {
  const fs::path root = run_dir / "checkpoints";
  fs::create_directories(root);
  const int64_t step = optimizer.stepCount();
  const fs::path folder = root / folderName(step);
  const fs::path partial = root / (folderName(step) + ".partial");
  // The checkpoint `latest` names is the state this run was resumed from, so it already holds
  // this step; rewriting it would leave `latest` naming a missing folder for a moment.
  if (fs::is_directory(folder) && readLatestCheckpointName(root / "latest") == folderName(step)) {
    pruneCheckpoints(run_dir, folder, keep_last);
    return folder;
  }
  // Every step's leftover, not only this one's: a checkpoint killed mid-write at a step the run
  // resumed past (a signal's, a time budget's) stayed for good (found by an outside probe). Only
  // the run holding the run's lock writes here.
  std::error_code listing;
  std::vector<fs::path> leftovers;
  for (fs::directory_iterator entry(root, listing), end; !listing && entry != end; entry.increment(listing)) {
    const std::string name = entry->path().filename().string();
    if (name.rfind("step_", 0) == 0 && name.size() > 8 && name.compare(name.size() - 8, 8, ".partial") == 0)
      leftovers.push_back(entry->path());
  }
  for (const fs::path& leftover : leftovers) fs::remove_all(leftover);
  fs::create_directories(partial);
  const std::string config_json = toJson(config).dump();
  try {
    saveModel(model, partial / "model.safetensors",
              {{"step", std::to_string(step)}, {"world_size", std::to_string(world_size)}, {"training_config", config_json}});
    writeFloatTensors(partial / "optimizer.safetensors", optimizer.state(),
                      {{"format", kTrainingStateFormat}, {"step", std::to_string(step)}, {"training_config", config_json}});
  } catch (...) {
    // A write that failed (a full disk) left the half-written folder on that disk until the next
    // resume (found by an outside probe).
    std::error_code ignored;
    fs::remove_all(partial, ignored);
    throw;
  }
  // A folder of this step that `latest` does not name (left by a run that stopped before updating
  // `latest`) is replaced; `latest` names another folder meanwhile, so a crash here loses nothing.
  const fs::path replaced = root / (folderName(step) + ".replaced");
  fs::remove_all(replaced);
  if (fs::exists(folder)) fs::rename(folder, replaced);
  fs::rename(partial, folder);
  fs::remove_all(replaced);
  writeTextAtomically(root / "latest", folderName(step) + "\n");
  pruneCheckpoints(run_dir, folder, keep_last);
  return folder;
}

std::vector<fs::path> trainingCheckpointFolders(const fs::path& run_dir) {
  std::vector<fs::path> folders;
  std::error_code error;
  for (fs::directory_iterator entry(run_dir / "checkpoints", error), end; !error && entry != end;
       entry.increment(error)) {
    const std::string name = entry->path().filename().string();
    if (entry->is_directory() && name.rfind("step_", 0) == 0 && name.find('.') == std::string::npos) {
      folders.push_back(entry->path());
    }
  }
  std::sort(folders.begin(), folders.end());
  return folders;
}

std::optional<CheckpointInfo> latestTrainingCheckpoint(const fs::path& run_dir) {
  const fs::path latest = run_dir / "checkpoints" / "latest";
  if (!fs::exists(latest)) return std::nullopt;
  const std::string name = readLatestCheckpointName(latest);
  if (!isCheckpointFolderName(name)) {
    throwInputError(latest.string(), 1, "expected the name of a step_<n> folder, got '" + name + "'");
  }
  CheckpointInfo info;
  info.folder = run_dir / "checkpoints" / name;
  const fs::path model_path = info.folder / "model.safetensors";
  if (!isCompleteCheckpoint(info.folder)) {
    // Say what is there to fall back on: the folders of earlier steps a run keeps (keep_last).
    std::string earlier;
    for (const fs::path& folder : trainingCheckpointFolders(run_dir))
      if (folder != info.folder && isCompleteCheckpoint(folder)) earlier = folder.filename().string();
    throwInputError(latest.string(), 1,
                    "checkpoint folder '" + info.folder.string() + "' is " +
                        (fs::exists(info.folder) ? "incomplete" : "missing") +
                        (earlier.empty() ? std::string()
                                         : "; to resume from the latest complete one, write '" + earlier + "' into " +
                                               latest.string()));
  }
  const auto archive = openSafetensors(model_path);
  // The tensors are verified as the model loads; the step and the settings are read here.
  verifyMetadataChecksum(*archive);
  // The run writes its float32 weights; a lower-precision copy in their place (ffloc convert
  // --dtype f16) would load, rounded, and the run would go on from other weights than it saved.
  for (const std::string& name : archive->names()) {
    if (const DType dtype = archive->at(name).dtype; dtype != DType::kF32) {
      throwInputError(model_path.string(), 0,
                      "tensor '" + name + "' is " + toString(dtype) +
                          ", but a run saves its weights as F32: this is not the file the run wrote, and "
                          "resuming from it would not continue the run exactly");
    }
  }
  info.step = parseCount(*archive, "step", 0);
  // Checkpoints from before data-parallel training were written by one process.
  info.world_size = archive->metadata().count("world_size") ? static_cast<int>(parseCount(*archive, "world_size", 1)) : 1;
  const std::string settings = model_path.string() + ": metadata 'training_config'";
  info.config = trainingConfigFromJson(parseJson(metadataField(*archive, "training_config"), settings), settings);
  return info;
}

std::optional<TrainingConfigProblem> resumeProblem(const CheckpointInfo& checkpoint, const TrainingConfig& config) {
  if (checkpoint.step <= config.steps) return std::nullopt;
  const fs::path run_dir = checkpoint.folder.parent_path().parent_path();
  return TrainingConfigProblem{"steps", std::to_string(config.steps) + ", but the run in " + run_dir.string() +
                                            " is already at step " + std::to_string(checkpoint.step) +
                                            "; ask for more steps to continue it"};
}

void loadOptimizerState(const CheckpointInfo& checkpoint, AdamW& optimizer) {
  const fs::path path = checkpoint.folder / "optimizer.safetensors";
  const auto archive = openSafetensors(path);
  verifyChecksums(*archive, torchThreadCount());
  const int64_t step = parseCount(*archive, "step", 0);
  if (step != checkpoint.step) {
    throwInputError(path.string(), 0, "metadata 'step' is " + std::to_string(step) + " but model.safetensors says " +
                                          std::to_string(checkpoint.step));
  }
  // An optimizer state copied from another run of the same step (another seed) was taken.
  const std::string settings = path.string() + ": metadata 'training_config'";
  const nlohmann::json saved =
      toJson(trainingConfigFromJson(parseJson(metadataField(*archive, "training_config"), settings), settings));
  const nlohmann::json expected = toJson(checkpoint.config);
  if (const std::optional<std::string> field = firstDifferingField(expected, saved))
    throwInputError(path.string(), 0, "metadata 'training_config': '" + *field + "' is " +
                                          saved.value(*field, nlohmann::json()).dump() + " but model.safetensors says " +
                                          expected.at(*field).dump() + ": the optimizer state is another run's");
  std::vector<std::pair<std::string, at::Tensor>> state;
  for (const std::string& name : archive->names()) state.emplace_back(name, toTorch(archive->at(name)));
  optimizer.loadState(state, step, path.string());
}

}  // namespace ffloc
