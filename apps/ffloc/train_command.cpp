// `ffloc train`: FastForward training (paper Eq. 2, appendix) on posed RGB-D datasets.
// Method, settings and file layout: docs/training.md.
#ifdef FFLOC_WITH_TORCH

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "command_options.h"
#include "commands.h"
#include "ffloc/core/clock.h"
#include "ffloc/core/error.h"
#include "ffloc/core/number_text.h"
#include "ffloc/core/stop_signals.h"
#include "ffloc/core/temporary_file.h"
#include "ffloc/core/text_file_writer.h"
#include "ffloc/core/writer_lock.h"
#include "ffloc/data/dataset.h"
#include "ffloc/data/splits.h"
#include "ffloc/io/input_file.h"
#include "ffloc/model/model_loader.h"
#include "ffloc/train/data_parallel.h"
#include "ffloc/train/local_launcher.h"
#include "ffloc/train/trainer.h"
#include "ffloc/train/training_checkpoint.h"

namespace ffloc::cli {
namespace {

namespace fs = std::filesystem;

struct TrainArguments {
  std::string config;
  std::vector<std::string> data;
  std::vector<std::string> validation_data;
  std::string out;
  bool resume = false;
  std::optional<int64_t> steps;
  std::optional<double> learning_rate;
  std::optional<uint64_t> seed;
  std::optional<std::string> device;
  std::optional<std::string> model;
  std::optional<int> threads;
  std::optional<std::string> precision;
  std::optional<int> batch_size;
  std::optional<int> accumulate;
  std::optional<int> loader_threads;
  int nproc_per_node = 1;
  double max_seconds = 0;
  double rendezvous_timeout_s = 1800;
  bool quiet = false;
};

// "DIR" or "DIR@<split>": a dataset, or only its frames of one split (e.g. a dataset's mapping
// split, so that its queries stay unseen for evaluation).
Scene loadTrainingData(const std::string& spec) {
  const size_t at = spec.rfind('@');
  if (at == std::string::npos) return loadDataset(spec);
  const std::string dir = spec.substr(0, at);
  const std::string split_name = spec.substr(at + 1);
  Split split = Split::kUnassigned;
  if (split_name == "mapping") {
    split = Split::kMapping;
  } else if (split_name == "query") {
    split = Split::kQuery;
  } else {
    throwInputError("--data", 0, "'" + spec + "': unknown split '" + split_name + "' (expected mapping or query)");
  }
  Scene scene = loadDataset(dir);
  requireSplits(scene);
  std::vector<Frame> kept;
  for (const size_t index : scene.indices(split)) kept.push_back(scene.frames[index]);
  scene.frames = std::move(kept);
  scene.points.clear();  // their observations index the frames that were dropped
  return scene;
}

// The dataset folder of a DIR[@split] spec and the split ("" for all its frames).
std::pair<fs::path, std::string> datasetParts(const std::string& spec) {
  const size_t at = spec.rfind('@');
  const std::string dir = at == std::string::npos ? spec : spec.substr(0, at);
  return {sameFolderKey(dir), at == std::string::npos ? std::string() : spec.substr(at + 1)};
}

// Whether two specs share frames: one folder, and all of it or the same split.
bool shareFrames(const std::string& a, const std::string& b) {
  const auto [dir, split] = datasetParts(a);
  const auto [other_dir, other_split] = datasetParts(b);
  return dir == other_dir && (split.empty() || other_split.empty() || split == other_split);
}

// Refuses a dataset given twice (`--data a,a`, or `a` beside `a@mapping`), which would pool its
// frames twice and weigh them double without a word. One dataset's two splits, DIR@mapping and
// DIR@query, are distinct frames and may be pooled.
void requireDistinctData(const std::vector<std::string>& specs, const std::string& flag) {
  for (size_t i = 0; i < specs.size(); ++i) {
    for (size_t j = 0; j < i; ++j) {
      if (shareFrames(specs[i], specs[j])) {
        throwInputError(flag, 0, "'" + specs[j] + "' and '" + specs[i] + "' are the same frames of " +
                                     datasetParts(specs[i]).first.string() +
                                     "; give each dataset once (DIR@mapping and DIR@query may be pooled)");
      }
    }
  }
}

// Validation on frames the run trains on measured nothing held out, without a word.
void requireHeldOut(const std::vector<std::string>& validation, const std::vector<std::string>& training) {
  for (const std::string& held_out : validation) {
    for (const std::string& trained : training) {
      if (shareFrames(held_out, trained)) {
        throw InputError("--val-data: '" + held_out + "' shares frames with '" + trained +
                         "' of --data, so validation would not be held out (DIR@query beside DIR@mapping is)");
      }
    }
  }
}

// ", match 42%" for a model with the matching head; "" for the others, whose 0 % read as a failure.
std::string matchText(bool matching, double accuracy) {
  if (!matching) return "";
  char text[32];
  std::snprintf(text, sizeof(text), ", match %.0f%%", 100.0 * accuracy);
  return text;
}

std::string validationSummary(const ValidationStats& stats, bool matching) {
  char text[256];
  std::snprintf(text, sizeof(text), "  val loss %.4f%s, pose median %.3g m / %.3g deg, %.0f%% in 10cm/10deg, %.0f%% in 25cm/5deg",
                stats.loss, matchText(matching, stats.match_accuracy).c_str(), stats.median_translation_error,
                stats.median_rotation_error_deg, 100.0 * stats.within_10cm_10deg, 100.0 * stats.within_25cm_5deg);
  return text;
}

const char* kCsvHeader =
    "step,loss,query_loss,map_loss,match_loss,match_accuracy,query_error,map_error,learning_rate,grad_norm,"
    "samples_per_s,step_s,data_wait_s,allreduce_s,optimizer_s,"
    "val_loss,val_query_error,val_map_error,val_match_accuracy,val_median_translation,val_median_rotation_deg,"
    "val_10cm_10deg,val_25cm_5deg\n";

// This process's command line, as the kernel holds it, for the ranks --nproc-per-node starts.
std::vector<std::string> ownArguments() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  std::vector<std::string> arguments;
  std::string argument;
  while (std::getline(in, argument, '\0')) arguments.push_back(argument);
  return arguments;
}

// The same command without --nproc-per-node, for each rank.
std::vector<std::string> rankArguments() {
  std::vector<std::string> out;
  const std::vector<std::string> all = ownArguments();
  for (size_t i = 0; i < all.size(); ++i) {
    if (all[i] == "--nproc-per-node") {
      ++i;
      continue;
    }
    if (all[i].rfind("--nproc-per-node=", 0) == 0) continue;
    out.push_back(all[i]);
  }
  return out;
}

// The config file's settings with the flags' overrides, and which flag set which field. A value
// that cannot make a run is refused naming the flag that set it; a field that no flag set is named
// with the config file.
struct CommandConfig {
  TrainingConfig config;
  std::map<std::string, std::string> flag_of_field;
  std::string origin;  // where a field no flag set comes from

  [[noreturn]] void refuse(const TrainingConfigProblem& problem) const {
    const auto flag = flag_of_field.find(problem.field);
    if (flag != flag_of_field.end()) throw InputError(flag->second + ": " + problem.message);
    throwInputError(origin, 0, "field '" + problem.field + "': " + problem.message);
  }
};

CommandConfig effectiveConfig(const TrainArguments& args, const DistributedEnvironment& environment) {
  // --resume without --config continues with the run's own settings: the defaults it took before
  // were refused as soon as the run had changed one that the optimisation depends on.
  std::string config_file = args.config;
  if (const fs::path run_config = fs::path(args.out) / "config.json"; config_file.empty() && args.resume) {
    if (fs::is_regular_file(run_config))
      config_file = run_config.string();
    else if (latestTrainingCheckpoint(args.out))
      // The defaults stood in, and the first setting the run had changed was reported instead.
      throwInputError(run_config.string(), 0, "missing, so the run's settings are unknown: pass them with --config");
  }
  CommandConfig command{config_file.empty() ? TrainingConfig{} : readTrainingConfig(config_file), {},
                        config_file.empty() ? "command line" : config_file + " with the command line"};
  TrainingConfig& config = command.config;
  const auto overrideWith = [&](auto& field, const auto& value, const std::string& name, const std::string& flag) {
    if (!value) return;
    field = *value;
    command.flag_of_field[name] = flag;
  };
  overrideWith(config.steps, args.steps, "steps", "--steps");
  overrideWith(config.learning_rate, args.learning_rate, "learning_rate", "--lr");
  overrideWith(config.seed, args.seed, "seed", "--seed");
  overrideWith(config.device, args.device, "device", "--device");
  overrideWith(config.model, args.model, "model", "--model");
  overrideWith(config.threads, args.threads, "threads", "--threads");
  overrideWith(config.precision, args.precision, "precision", "--precision");
  overrideWith(config.batch_size, args.batch_size, "batch_size", "--batch-size");
  overrideWith(config.accumulate, args.accumulate, "accumulate", "--accumulate");
  overrideWith(config.loader_threads, args.loader_threads, "loader_threads", "--loader-threads");
  // Ranks on one machine share its cores rather than each taking them all.
  if (config.threads == 0 && environment.local_world_size > 1) {
    config.threads = std::max(1, static_cast<int>(std::thread::hardware_concurrency()) / environment.local_world_size);
  }
  if (const auto problem = config.problem()) command.refuse(*problem);
  return command;
}

// The run folder's entries, each as the run writes it (or absent): one of another kind ended the
// run after its training in an internal error (a file named checkpoints) or was never written, in
// silence (a folder named config.json).
void requireEntryKind(const fs::path& path, fs::file_type kind) {
  std::error_code error;
  const fs::file_status status = fs::symlink_status(path, error);
  if (!fs::exists(status)) return;
  if (status.type() == kind || (fs::is_symlink(status) && fs::status(path, error).type() == kind)) return;
  throwInputError(path.string(), 0, std::string("exists and is not ") +
                                        (kind == fs::file_type::directory ? "a folder" : "a file") +
                                        "; the run writes it there: move it away or choose another --out");
}

// What the run's lock protects: two runs resuming into one folder at once both wrote its
// checkpoints and its log.
fs::path runLockTarget(const fs::path& run_dir) { return run_dir / "run"; }

// Rows after the header: the steps an earlier run logged.
bool logHasRows(const fs::path& log_path) {
  std::ifstream log(log_path);
  std::string line;
  return std::getline(log, line) && std::getline(log, line) && !line.empty();
}

// --out, before anything is read from it or written: the file system's own errors ("cannot
// create directories: Not a directory") named nothing and ended as internal errors. A new run
// into a folder holding an earlier one's checkpoints or logged steps is refused: without
// `latest` (a run killed before its first one was named) it deleted them and rewrote the log.
void checkRunFolder(const fs::path& run_dir, bool resume) {
  std::error_code error;
  const fs::file_status status = fs::status(run_dir, error);
  if (fs::exists(status) && !fs::is_directory(status)) {
    throw InputError("--out: '" + run_dir.string() + "' exists and is not a folder");
  }
  if (error && error != std::errc::no_such_file_or_directory) {
    throw InputError("--out: '" + run_dir.string() + "': " + error.message());
  }
  if (!fs::exists(status)) return;
  const fs::path checkpoints = run_dir / "checkpoints";
  requireEntryKind(checkpoints, fs::file_type::directory);
  requireEntryKind(checkpoints / "latest", fs::file_type::regular);
  requireEntryKind(run_dir / "config.json", fs::file_type::regular);
  requireEntryKind(run_dir / "log.csv", fs::file_type::regular);
  requireEntryKind(writerLockFile(runLockTarget(run_dir)), fs::file_type::regular);
  const std::vector<fs::path> folders = trainingCheckpointFolders(run_dir);
  const std::string newest_step = folders.empty() ? std::string() : folders.back().filename().string();
  const bool named = fs::exists(checkpoints / "latest");
  if (resume && !named && !newest_step.empty()) {
    throwInputError((checkpoints / "latest").string(), 0,
                    "missing, so no checkpoint is named to resume from, but " + newest_step +
                        " is there (a run stopped before naming its first checkpoint); to resume from it, "
                        "write its name into that file");
  }
  // A run killed before its first checkpoint was refused as a new run ("pass --resume") and as a
  // resumed one ("no checkpoint"), neither saying how to go on.
  const bool checkpointed = named || !newest_step.empty();
  const std::string stopped_early = "a run that stopped before its first checkpoint (steps in log.csv, nothing to "
                                    "resume): choose another --out, or remove log.csv to start over here";
  if (resume && !checkpointed && logHasRows(run_dir / "log.csv")) throwInputError(run_dir.string(), 0, "holds " + stopped_early);
  if (!resume && checkpointed)
    throwInputError(run_dir.string(), 0, "already holds a training run (checkpoints); pass --resume to continue it, "
                                         "or choose another --out");
  if (!resume && logHasRows(run_dir / "log.csv")) throwInputError(run_dir.string(), 0, "already holds " + stopped_early);
  // `--out /` or a dataset's folder took the run's files in among others.
  if (!resume) {
    for (fs::directory_iterator entry(run_dir, error), end; !error && entry != end; entry.increment(error)) {
      const std::string name = entry->path().filename().string();
      if (name == "checkpoints" || name == "config.json" || name == "log.csv" || name.rfind('.', 0) == 0) continue;
      throw InputError("--out: '" + run_dir.string() + "' holds other files ('" + name +
                       "', ...); give a new or empty folder, or a run's folder with --resume");
    }
  }
}

// Ranks started with other settings (another --lr, --batch-size or --model) trained apart
// without a word, or died inside a collective with gloo's message.
void requireTheSameSettingsOnEveryRank(DataParallel& parallel, const TrainingConfig& config, int64_t resumed_from_step) {
  nlohmann::json own = toJson(config);
  // A rank that resumes from another step (a run folder not shared) ran another number of steps.
  own["resumed_from_step"] = resumed_from_step;
  const nlohmann::json lead = nlohmann::json::parse(parallel.broadcastTextFromRankZero(own.dump()));
  std::string difference;
  // Each machine's own: the cores and memory its ranks share.
  if (const std::optional<std::string> field =
          firstDifferingField(own, lead, {"threads", "loader_threads", "prefetch_samples"}))
    difference = "field '" + *field + "' is " + own.at(*field).dump() + " here but " +
                 lead.value(*field, nlohmann::json()).dump() + " on rank 0";
  if (parallel.anyRank(!difference.empty())) {
    const int rank = parallel.environment().rank;
    throw InputError("rank " + std::to_string(rank) + ": the ranks were started with different settings" +
                     (difference.empty() ? " (the other ranks say which)" : ": " + difference) +
                     "; start every rank with the same config and flags");
  }
}

// A run refused after it made its --out folder (a model that names no parameter, a rank that
// never joined, data where no sample can be drawn) left that folder behind; it goes, unless
// something but the lock and the files this run wrote at its start, as it wrote them, is in it
// (a log with rows stays, and with it the folder). Made after the run's lock is declared, so
// that it is destroyed while the lock is still held.
class RemoveNewFolderOnError {
 public:
  // Only rank 0 removes: the other ranks may share the folder with it.
  RemoveNewFolderOnError(fs::path folder, fs::path lock_name, bool lead)
      : folder_(std::move(folder)), lock_name_(std::move(lock_name)) {
    std::error_code error;
    made_here_ = lead && !fs::exists(folder_, error) && !error;
    // The parents --out makes with it go too: those of the path as it resolves ("x/../keep/run"
    // names the folder keep, which exists, however new x is; "a/b/run/" has the parent a/b).
    fs::path resolved = fs::weakly_canonical(fs::absolute(folder_, error), error);
    if (!resolved.has_filename()) resolved = resolved.parent_path();
    for (fs::path parent = resolved.parent_path();
         made_here_ && !error && parent.has_relative_path() && !fs::exists(parent, error);
         parent = parent.parent_path())
      new_parents_.push_back(parent);
  }
  RemoveNewFolderOnError(const RemoveNewFolderOnError&) = delete;
  RemoveNewFolderOnError& operator=(const RemoveNewFolderOnError&) = delete;
  // `name`, in the folder, was written by this run and is now `bytes` long.
  void wrote(const fs::path& name, uintmax_t bytes) { written_.emplace_back(name, bytes); }

  ~RemoveNewFolderOnError() {
    if (!made_here_ || std::uncaught_exceptions() == 0) return;
    std::error_code error;
    for (fs::directory_iterator entry(folder_, error), end; !error && entry != end; entry.increment(error)) {
      const fs::path name = entry->path().filename();
      if (name == lock_name_) continue;
      const auto ours = std::find_if(written_.begin(), written_.end(), [&](const auto& file) { return file.first == name; });
      if (ours == written_.end() || fs::file_size(entry->path(), error) != ours->second || error) return;
    }
    if (error) return;
    for (const auto& file : written_) fs::remove(folder_ / file.first, error);
    fs::remove(folder_ / lock_name_, error);
    // Not recursive: whatever came in meanwhile stays, and so do the folders above it.
    if (!fs::remove(folder_, error)) return;
    for (const fs::path& parent : new_parents_)
      if (!fs::remove(parent, error)) return;
  }

 private:
  fs::path folder_;
  fs::path lock_name_;
  bool made_here_ = false;
  std::vector<fs::path> new_parents_;  // deepest first
  std::vector<std::pair<fs::path, uintmax_t>> written_;
};

// `file` as it was (or gone, if it was not there) when the scope ends by an exception, unless
// released first.
class PutBackOnError {
 public:
  PutBackOnError(fs::path file, std::optional<std::string> before) : file_(std::move(file)), before_(std::move(before)) {}
  PutBackOnError(const PutBackOnError&) = delete;
  PutBackOnError& operator=(const PutBackOnError&) = delete;
  ~PutBackOnError() {
    if (released_ || std::uncaught_exceptions() == 0) return;
    std::error_code ignored;
    try {
      if (before_) {
        writeTextFile(file_, *before_);
      } else {
        fs::remove(file_, ignored);
      }
    } catch (const std::exception&) {
      // The error on its way out says what went wrong; this one would hide it.
    }
  }
  void release() { released_ = true; }

 private:
  fs::path file_;
  std::optional<std::string> before_;
  bool released_ = false;
};

// The first stop signal (SIGINT, SIGTERM, SIGHUP) stops the run after the step in progress, with
// a checkpoint; a second ends it at once. A Ctrl-C killed the run silently and lost every step
// since the last checkpoint. Under the launcher every rank receives the signal and they agree on the step.
volatile sig_atomic_t stop_signal = 0;
volatile sig_atomic_t announce_stop = 0;

void stopAfterThisStep(int signal_number) {
  if (stop_signal != 0) removeTemporaryFilesAndRaise(signal_number);
  stop_signal = signal_number;
  if (announce_stop) {
    constexpr char kMessage[] = "\nstopping after this step, with a checkpoint (the signal again stops at once)\n";
    [[maybe_unused]] const ssize_t written = ::write(STDERR_FILENO, kMessage, sizeof(kMessage) - 1);
  }
}

// Exit code: 0, or 128 + the signal that stopped the run.
int runTrain(const TrainArguments& args) {
  const DistributedEnvironment environment = DistributedEnvironment::fromProcessEnvironment();
  const CommandConfig command = effectiveConfig(args, environment);
  const TrainingConfig& config = command.config;
  const fs::path run_dir = args.out;
  checkRunFolder(run_dir, args.resume);
  if (const auto checkpoint = args.resume ? latestTrainingCheckpoint(run_dir) : std::nullopt) {
    if (const auto problem = resumeProblem(*checkpoint, config)) command.refuse(*problem);
  } else if (const std::string problem = modelSpecProblem(config.model); !problem.empty()) {
    // Before the data loads and --out is made: the model is read only after both.
    command.refuse({"model", problem});
  }
  const bool lead = environment.rank == 0;

  requireDistinctData(args.data, "--data");
  requireDistinctData(args.validation_data, "--val-data");
  requireHeldOut(args.validation_data, args.data);
  std::vector<Scene> scenes;
  for (const std::string& spec : args.data) scenes.push_back(loadTrainingData(spec));
  for (const Scene& scene : scenes)
    if (liesWithin(run_dir, scene.root))
      throw InputError("--out: '" + run_dir.string() + "' is inside the dataset '" + scene.root.string() +
                       "'; write the run elsewhere");
  const fs::path lock_target = runLockTarget(run_dir);
  std::optional<WriterLock> run_lock;
  RemoveNewFolderOnError cleanup(run_dir, writerLockFile(lock_target).filename(), lead);
  std::error_code error;
  fs::create_directories(run_dir, error);
  if (error) throw InputError("--out: cannot create '" + run_dir.string() + "': " + error.message());
  if (lead) {
    run_lock.emplace(lock_target, [&] {
      throw InputError("--out: '" + run_dir.string() + "' is in use by another 'ffloc train'; wait for it to end");
    });
  }
  std::vector<Scene> validation_scenes;
  for (const std::string& spec : args.validation_data) validation_scenes.push_back(loadTrainingData(spec));
  // Datasets that would never be sampled were taken without a word, a split too small among them.
  if (!args.validation_data.empty() && config.validation_every == 0) {
    throw InputError("--val-data: validation is off (validation_every is 0); set validation_every in the config to "
                     "validate on these datasets");
  }
  std::unique_ptr<DataParallel> parallel;
  if (environment.distributed()) {
    if (!args.quiet)
      std::cerr << "rank " << environment.rank << " of " << environment.world_size << ": joining at "
                << environment.master_addr << ":" << environment.master_port << " (waiting up to "
                << args.rendezvous_timeout_s << " s for the other ranks)\n";
    parallel = std::make_unique<DataParallel>(environment, config.device == "cuda", args.rendezvous_timeout_s);
    const auto checkpoint = args.resume ? latestTrainingCheckpoint(run_dir) : std::nullopt;
    requireTheSameSettingsOnEveryRank(*parallel, config, checkpoint ? checkpoint->step : 0);
  }
  std::unique_ptr<Trainer> made;
  try {
    made = std::make_unique<Trainer>(config, std::move(scenes), run_dir, args.resume, std::move(validation_scenes),
                                        parallel.get());
  } catch (const TrainingConfigError& error) {
    command.refuse(error.problem());
  }
  Trainer& trainer = *made;
  // A fine-tune whose config left long_side at its default went on at another image size than the
  // model had learned, without a word (found by an outside probe).
  if (lead && !args.resume && config.model.rfind("random:", 0) != 0 &&
      trainer.initialInputLongSide() != config.long_side)
    std::cerr << "note: the model learned at long_side " << trainer.initialInputLongSide() << "; this run trains at "
              << config.long_side << " (long_side; set it to " << trainer.initialInputLongSide()
              << " to keep the model's size), and its checkpoints record that size\n";
  using Clock = std::chrono::steady_clock;
  const Clock::time_point started = Clock::now();
  const auto budgetSpent = [&] { return args.max_seconds > 0 && secondsSince(started) > args.max_seconds; };
  const auto stopAsked = [&] { return budgetSpent() || stop_signal != 0; };
  announce_stop = lead && !args.quiet ? 1 : 0;
  const StopSignalHandler stop_on_signal(stopAfterThisStep, StopSignalHandler::Ignored::kKept);
  // Each rank asks on its own clock; the stop takes effect on all of them at the same step.
  const auto trainStep = [&] {
    if (stopAsked()) trainer.requestStop();
    return trainer.step();
  };
  const auto exitCode = [] { return stop_signal != 0 ? 128 + static_cast<int>(stop_signal) : 0; };
  if (!lead) {
    // The other ranks compute and keep in step through the collectives; rank 0 alone writes.
    while (trainer.stepsDone() < config.steps && !trainStep().stop_requested) {
    }
    return exitCode();
  }
  // A resume refused before its first step (data where no sample can be drawn) left the run's
  // config.json rewritten with its settings: a --steps 10 that never ran became the run's (found
  // by an outside probe). Put back until a step is done.
  std::optional<std::string> config_before;
  if (args.resume && fs::is_regular_file(run_dir / "config.json")) {
    std::ifstream in(run_dir / "config.json", std::ios::binary);
    config_before = std::string(std::istreambuf_iterator<char>(in), {});
  }
  PutBackOnError config_guard(run_dir / "config.json", config_before);
  const std::string config_text = toJson(config).dump(2) + "\n";
  writeTextFile(run_dir / "config.json", config_text);
  cleanup.wrote("config.json", config_text.size());
  const fs::path log_path = run_dir / "log.csv";
  // A log without even its header (a run killed before its first row) is started again.
  const bool new_log = !args.resume || !fs::exists(log_path) || fs::file_size(log_path) == 0;
  if (!new_log) {
    std::ifstream existing(log_path);
    std::string header;
    std::getline(existing, header);
    if (header + "\n" != kCsvHeader) {
      throwInputError(log_path.string(), 1, "columns differ from this version's log (" + std::string(kCsvHeader) +
                                                "); move the old log away to resume");
    }
    // Rows logged after the checkpoint resumed from are run again: kept, they appeared twice.
    std::string kept = header + "\n";
    bool dropped = false;
    for (std::string row; std::getline(existing, row);) {
      char* end = nullptr;
      const long long step = std::strtoll(row.c_str(), &end, 10);
      // A row cut short by a kill (no line end, or no comma after its step) goes too.
      if (existing.eof() || *end != ',' || step > trainer.stepsDone()) {
        dropped = true;
      } else {
        kept += row + "\n";
      }
    }
    if (dropped) writeTextFile(log_path, kept);
  }
  std::ofstream log(log_path, new_log ? std::ios::trunc : std::ios::app);
  if (!log) throwInputError(log_path.string(), 0, "cannot write the training log");
  if (new_log) {
    log << kCsvHeader << std::flush;
    cleanup.wrote(log_path.filename(), std::string(kCsvHeader).size());
  }
  if (!args.quiet) {
    std::cerr << "model: " << trainer.modelDescription() << "; " << trainer.trainableParameterCount()
              << " trainable parameters" << (config.train_encoder ? "" : " (encoder frozen)") << "\n"
              << "steps " << trainer.stepsDone() << " -> " << config.steps << ", global batch "
              << trainer.globalBatch() << " (" << config.batch_size << " x " << config.accumulate << " passes x "
              << environment.world_size << " ranks), run folder " << run_dir.string() << "\n";
  }

  Clock::time_point window_start = Clock::now();
  double last_validation_seconds = 0;
  int64_t window_steps = 0;
  double window_loss = 0;
  // Rank 0's time per step over the window: whole step, waiting for data, all-reduce, optimiser.
  double window_step = 0, window_wait = 0, window_allreduce = 0, window_optimizer = 0;
  std::string stopped;  // why the run ends before config.steps
  while (trainer.stepsDone() < config.steps) {
    const TrainingStepStats stats = trainStep();
    config_guard.release();
    // Ranks agree on a stop inside the next step; a run of one rank stops after the step that
    // spent its budget rather than running one more.
    bool stop = stats.stop_requested || (!environment.distributed() && stopAsked());
    ++window_steps;
    window_loss += stats.loss;
    window_step += stats.step_seconds;
    window_wait += stats.data_wait_seconds;
    window_allreduce += stats.allreduce_seconds;
    window_optimizer += stats.optimizer_seconds;
    const bool log_now = stats.step % config.log_every == 0 || stats.step == config.steps || stop;
    const bool validate_now = config.validation_every > 0 && stats.step % config.validation_every == 0;
    // Checkpoints are not tied to log steps: checkpoint_every 3 with log_every 5 wrote only every
    // 15th step's.
    if (log_now || validate_now) {
      const double seconds = secondsSince(window_start);
      const double rate = seconds > 0 ? static_cast<double>(window_steps) / seconds : 0.0;
      const double sample_rate = rate * static_cast<double>(trainer.globalBatch());
      const double steps_in_window = static_cast<double>(window_steps);
      const double wait_share = window_step > 0 ? window_wait / window_step : 0.0;
      std::optional<ValidationStats> validation;
      if (validate_now) {
        const Clock::time_point validation_start = Clock::now();
        validation = trainer.validate(args.quiet, [&] { return !stopAsked(); });
        last_validation_seconds = secondsSince(validation_start);
        // Scores of part of the samples would not compare with the other rows.
        if (validation->samples < config.validation_samples) {
          if (!args.quiet)
            std::cerr << "validation cut short after " << validation->samples << " of " << config.validation_samples
                      << " samples; not logged\n";
          validation.reset();
        }
        stop = stop || (!environment.distributed() && stopAsked());
      }
      char row[512];
      std::snprintf(row, sizeof(row), "%lld,%.6g,%.6g,%.6g,%.6g,%.4g,%.6g,%.6g,%.6g,%.6g,%.4g,%.4g,%.4g,%.4g,%.4g,",
                    static_cast<long long>(stats.step), stats.loss, stats.query_loss, stats.map_loss, stats.match_loss,
                    stats.match_accuracy, stats.query_error,
                    stats.map_error, stats.learning_rate, stats.grad_norm, sample_rate, window_step / steps_in_window,
                    window_wait / steps_in_window, window_allreduce / steps_in_window, window_optimizer / steps_in_window);
      log << row;
      if (validation) {
        std::snprintf(row, sizeof(row), "%.6g,%.6g,%.6g,%.4g,%.6g,%.6g,%.4g,%.4g", validation->loss,
                      validation->query_error, validation->map_error, validation->match_accuracy,
                      validation->median_translation_error,
                      validation->median_rotation_error_deg, validation->within_10cm_10deg,
                      validation->within_25cm_5deg);
        log << row;
      } else {
        log << ",,,,,,,";
      }
      log << "\n" << std::flush;
      if (!args.quiet) {
        // The validations still to come at the last one's pace: an eta of 3 s once preceded a
        // validation of 2000 samples (found by an outside probe).
        const int64_t validations_left =
            config.validation_every > 0 ? config.steps / config.validation_every - stats.step / config.validation_every : 0;
        const double eta = (rate > 0 ? static_cast<double>(config.steps - stats.step) / rate : 0.0) +
                           static_cast<double>(validations_left) * last_validation_seconds;
        const bool matching = trainer.model().config().query_head == QueryHeadKind::kMatching;
        std::fprintf(stderr,
                     "step %lld/%lld  loss %.4f (mean %.4f)  err q %.3f m %.3f%s  lr %.2e  |g| %.3g"
                     "  %.2f samples/s (%.0f%% waiting for data)  eta %.0f s%s\n",
                     static_cast<long long>(stats.step), static_cast<long long>(config.steps), stats.loss,
                     window_loss / static_cast<double>(window_steps), stats.query_error, stats.map_error,
                     matchText(matching, stats.match_accuracy).c_str(), stats.learning_rate, stats.grad_norm,
                     sample_rate, 100.0 * wait_share, eta,
                     validation ? validationSummary(*validation, matching).c_str() : "");
      }
      window_start = Clock::now();
      window_steps = 0;
      window_loss = 0;
      window_step = 0;
      window_wait = 0;
      window_allreduce = 0;
      window_optimizer = 0;
    }
    if (stop) {
      // Said once the checkpoint is written: a second signal during the write leaves none.
      if (stop_signal != 0)
        stopped = "stopped by " + signalName(stop_signal) + " at step " + std::to_string(stats.step) +
                  "; --resume continues from this checkpoint";
      else if (budgetSpent() && stats.step == config.steps)
        stopped.clear();  // finished: the budget ran out at the last step
      else if (budgetSpent())
        stopped = "time budget of " + formatNumber(args.max_seconds) + " s spent at step " +
                  std::to_string(stats.step) + " of " + std::to_string(config.steps) +
                  "; --resume continues from this checkpoint";
      else
        stopped = "stopped at step " + std::to_string(stats.step) +
                  ": another rank was stopped (a signal or its time budget); --resume continues from this checkpoint";
      break;
    }
    if (stats.step % config.checkpoint_every == 0 && stats.step != config.steps) trainer.saveCheckpoint();
  }
  const fs::path folder = trainer.saveCheckpoint();
  // Not progress: with --quiet a run cut short by its budget looked finished (exit 0, no output).
  if (!stopped.empty()) std::cerr << stopped << "\n";
  if (!args.quiet) std::cerr << "checkpoint: " << (folder / "model.safetensors").string() << "\n";
  return exitCode();
}

}  // namespace

void registerTrainCommand(CLI::App& app, CommandRun& run) {
  auto args = std::make_shared<TrainArguments>();
  CLI::App* cmd = app.add_subcommand("train", "Train FastForward on posed RGB-D datasets (docs/training.md)");
  cmd->add_option("--config", args->config, "Training settings (JSON; see docs/training.md)");
  cmd->add_option("--data", args->data, "Dataset folders (any format ffloc reads, with depth); DIR@mapping or DIR@query keeps one split")
      ->required()
      ->delimiter(',')
      ->check(nonEmptyPath());
  cmd->add_option("--val-data", args->validation_data,
                  "Held-out datasets for validation (loss and PnP pose); default: samples of --data")
      ->delimiter(',')
      ->check(nonEmptyPath());
  cmd->add_option("--out", args->out, "Run folder: log.csv, config.json, checkpoints/")->required()->check(nonEmptyPath());
  cmd->add_flag("--resume", args->resume, "Continue from the latest checkpoint in the run folder");
  cmd->add_option("--steps", args->steps, "Total optimiser steps (overrides the config)");
  cmd->add_option("--lr", args->learning_rate, "Peak learning rate (overrides the config)");
  cmd->add_option("--seed", args->seed, "Run seed (overrides the config)")->check(wholeNumber());
  cmd->add_option("--device", args->device, "cpu or cuda (overrides the config)");
  cmd->add_option("--model", args->model, "Initial weights (overrides the config): checkpoint or random:<preset>");
  cmd->add_option("--threads", args->threads, "libtorch threads, 0 = all cores (overrides the config)")
      ->check(threadCountRange());
  cmd->add_option("--precision", args->precision, "fp32, or bf16 mixed precision (overrides the config)")
      ->check(CLI::IsMember({"fp32", "bf16"}));
  cmd->add_option("--batch-size", args->batch_size, "Samples in one forward pass of each rank (overrides the config)");
  cmd->add_option("--accumulate", args->accumulate, "Forward passes per optimiser step (overrides the config)");
  cmd->add_option("--loader-threads", args->loader_threads,
                  "Background threads preparing samples (overrides the config)");
  cmd->add_option("--nproc-per-node", args->nproc_per_node,
                  "Start this many ranks on this machine, as torchrun does (RANK, WORLD_SIZE, ... set for each)")
      ->check(CLI::Validator(
          [](const std::string& input) -> std::string {
            int64_t ranks = 0;
            if (!CLI::detail::lexical_cast(input, ranks)) return "expected an integer, got " + input;
            return localRanksProblem(ranks);
          },
          "RANKS"));
  cmd->add_option("--max-seconds", args->max_seconds,
                  "Stop after this many seconds of training with a checkpoint (0: run all steps)")
      ->check(secondsIn(0, std::numeric_limits<double>::infinity()));
  cmd->add_option("--rendezvous-timeout", args->rendezvous_timeout_s,
                  "Distributed runs: seconds a rank waits for the others to join before it gives up")
      ->capture_default_str()
      ->check(secondsIn(1, 86400));
  cmd->add_flag("--quiet", args->quiet, "No progress output (why a run stopped early is still said)");
  cmd->callback([args, &run] {
    run = [args] {
      if (args->nproc_per_node > 1) {
        // Under torchrun or a scheduler each process started a private run of its own.
        for (const char* variable : {"RANK", "WORLD_SIZE"})
          if (const char* value = std::getenv(variable); value && *value)
            throw InputError(std::string("--nproc-per-node: this process is already a rank (") + variable + "=" +
                             value + ", as torchrun and schedulers set it); drop --nproc-per-node, or unset " +
                             variable + " to start the ranks here");
        return runLocalRanks(rankArguments(), args->nproc_per_node);
      }
      return runTrain(*args);
    };
  });
}

}  // namespace ffloc::cli

#endif  // FFLOC_WITH_TORCH
