// `ffloc train` refusing bad input before it writes anything, stopping on a signal or a time budget,
// and the launcher's bound on ranks.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "ffloc/core/error.h"
#include "ffloc/core/writer_lock.h"
#include "ffloc/train/local_launcher.h"
#include "ffloc/train/training_test_util.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

// 1000 ranks forked about 100 processes on 2 cores that never got anywhere.
TEST(LocalLauncher, StartsAtMostOneRankPerHardwareThread) {
  const int64_t most = std::max(1u, std::thread::hardware_concurrency());
  EXPECT_EQ(localRanksProblem(1), "");
  EXPECT_EQ(localRanksProblem(most), "");
  EXPECT_EQ(localRanksProblem(most + 1), "must be in [1, " + std::to_string(most) +
                                             "] (one rank per hardware thread of this machine at most), got " +
                                             std::to_string(most + 1));
  EXPECT_NE(localRanksProblem(0), "");
  try {
    runLocalRanks({"/bin/true"}, 1000);
    ADD_FAILURE() << "1000 ranks were started";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("ranks: must be in [1, ", 0), 0u) << e.what();
  }
}

#ifdef FFLOC_CLI_PATH
class TrainCommandInput : public ::testing::Test {
 protected:
  void SetUp() override { root_ = testing::makeTempDir("ffloc-train-input"); }

  // Exit status of `ffloc train <arguments>`; its output goes to output().
  int train(const std::string& arguments) {
    const std::string command = std::string(FFLOC_CLI_PATH) + " train --quiet --data " +
                                testing::smallScene().root.string() + " " + arguments + " > " +
                                (root_ / "output.txt").string() + " 2>&1";
    const int status = std::system(command.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  std::string output() const {
    std::ifstream in(root_ / "output.txt");
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
  }

  std::string config(const std::string& json) {
    const fs::path file = root_ / "c.json";
    std::ofstream(file) << json;
    return file.string();
  }

  bool contains(const std::string& part) const { return output().find(part) != std::string::npos; }

  // testing::smallConfig() for `steps` steps, without warm-up.
  static TrainingConfig settingsFor(int64_t steps) {
    TrainingConfig settings = testing::smallConfig();
    settings.steps = steps;
    settings.warmup_steps = 0;
    return settings;
  }

  fs::path root_;
};

// Each of these was an internal error (exit 3); learning_rate 1e300 also left config.json and an
// empty log.csv behind.
TEST_F(TrainCommandInput, RefusesARunFolderItCannotUseAndAnOverflowingRateBeforeWritingAnything) {
  const fs::path file = root_ / "afile";
  std::ofstream(file) << "hi\n";
  EXPECT_EQ(train("--out " + file.string()), 2) << output();
  EXPECT_TRUE(contains("error: --out: '" + file.string() + "' exists and is not a folder")) << output();
  std::ifstream kept(file);
  std::string line;
  std::getline(kept, line);
  EXPECT_EQ(line, "hi");

  EXPECT_EQ(train("--out ''"), 2) << output();
  EXPECT_TRUE(contains("--out")) << output();

  const fs::path loop = root_ / "loop";
  fs::create_symlink(loop, loop);
  EXPECT_EQ(train("--out " + loop.string()), 2) << output();
  EXPECT_TRUE(contains("error: --out: '" + loop.string() + "': ")) << output();

  const fs::path run = root_ / "run";
  const std::string bad_rate = config(R"({"steps": 1, "warmup_steps": 0, "learning_rate": 1e300})");
  EXPECT_EQ(train("--config " + bad_rate + " --out " + run.string()), 2) << output();
  EXPECT_TRUE(contains("error: " + bad_rate + ": field 'learning_rate': must be in (0, 1], got 1e+300")) << output();
  EXPECT_FALSE(fs::exists(run));

  // Refused after --out was made (the validation data is read then): it goes, and so do the
  // parents it was made with, which stayed before.
  const std::string missing_data = " --val-data " + (root_ / "missing").string();
  EXPECT_EQ(train("--out " + (root_ / "new" / "deeper" / "run").string() + missing_data), 2) << output();
  EXPECT_TRUE(contains("missing")) << output();
  EXPECT_FALSE(fs::exists(root_ / "new")) << output();
  EXPECT_TRUE(fs::exists(root_));
  EXPECT_EQ(train("--out " + (root_ / "new" / "deeper" / "run").string() + "/" + missing_data), 2) << output();
  EXPECT_FALSE(fs::exists(root_ / "new")) << "a trailing slash";
  // Through a folder that does not exist yet to one that does: that one stays, empty as it is.
  fs::create_directories(root_ / "keep");
  EXPECT_EQ(train("--out " + (root_ / "x" / ".." / "keep" / "run").string() + missing_data), 2) << output();
  EXPECT_TRUE(fs::exists(root_ / "keep"));
  EXPECT_FALSE(fs::exists(root_ / "keep" / "run"));

  // The second of two equal keys won silently: this trained 1 step.
  const std::string twice = config(R"({"steps": 10, "warmup_steps": 0, "steps": 1})");
  EXPECT_EQ(train("--config " + twice + " --out " + run.string()), 2) << output();
  EXPECT_TRUE(contains("error: " + twice + ": field 'steps': duplicated key")) << output();
  EXPECT_FALSE(fs::exists(run));
}

// Flags that override the config are named as typed: --lr inf wrote "learning_rate": null, which
// no resume could read, and --accumulate 1000000000 made one step run for days.
TEST_F(TrainCommandInput, NamesTheFlagThatSetABadValue) {
  const fs::path run = root_ / "run";
  const std::string short_run = config(R"({"steps": 1, "warmup_steps": 0})");
  EXPECT_EQ(train("--config " + short_run + " --out " + run.string() + " --lr inf"), 2) << output();
  EXPECT_TRUE(contains("error: --lr: must be in (0, 1], got inf")) << output();
  EXPECT_EQ(train("--config " + short_run + " --out " + run.string() + " --accumulate 1000000000"), 2) << output();
  EXPECT_TRUE(contains("error: --accumulate: must be in [1, 1024], got 1000000000")) << output();
  EXPECT_EQ(train("--config " + short_run + " --out " + run.string() + " --nproc-per-node 100000"), 2) << output();
  EXPECT_TRUE(contains("--nproc-per-node: must be in [1, ")) << output();
  // Under torchrun or a scheduler every process started a private run of its own.
  ::setenv("RANK", "1", 1);
  ::setenv("WORLD_SIZE", "4", 1);
  const int as_a_rank = train("--config " + short_run + " --out " + run.string() + " --nproc-per-node 2");
  ::unsetenv("RANK");
  ::unsetenv("WORLD_SIZE");
  EXPECT_EQ(as_a_rank, 2) << output();
  EXPECT_TRUE(contains("error: --nproc-per-node: this process is already a rank (RANK=1")) << output();
  // NaN passed CLI11's non-negative check and the budget never ran out; an empty data path said
  // "error: : Invalid argument".
  EXPECT_EQ(train("--config " + short_run + " --out " + run.string() + " --max-seconds nan"), 2) << output();
  EXPECT_TRUE(contains("--max-seconds: must be a finite number of seconds, at least 0, got nan")) << output();
  EXPECT_EQ(train("--config " + short_run + " --out " + run.string() + " --val-data ''"), 2) << output();
  EXPECT_TRUE(contains("--val-data: the path is empty")) << output();
  EXPECT_FALSE(fs::exists(run));

  // A model that cannot be had was found only after the data loaded (and --out was made), and
  // was named as the flag when the config file gave it.
  const std::string huge_model = config(R"({"steps": 1, "warmup_steps": 0, "model": "random:huge"})");
  EXPECT_EQ(train("--config " + huge_model + " --out " + run.string()), 2) << output();
  EXPECT_TRUE(contains("error: " + huge_model + " with the command line: field 'model': 'random:huge': unknown preset"))
      << output();
  EXPECT_EQ(train("--config " + short_run + " --out " + run.string() + " --model " + (root_ / "none").string()), 2)
      << output();
  EXPECT_TRUE(contains("error: --model: '" + (root_ / "none").string() + "': no such file")) << output();
  EXPECT_FALSE(fs::exists(run));
  // Found only once the model is built: it said "training config", and left --out behind empty.
  TrainingConfig no_such_part = settingsFor(1);
  no_such_part.trained_parameters = {"no_such_part."};
  const std::string part_config = config(toJson(no_such_part).dump());
  EXPECT_EQ(train("--config " + part_config + " --out " + run.string()), 2) << output();
  EXPECT_TRUE(contains("error: " + part_config + " with the command line: field 'trained_parameters': 'no_such_part.'"))
      << output();
  EXPECT_FALSE(fs::exists(run));
  // Found at the first draw, after config.json and the log's header were written: they stayed,
  // though the docs say a refused run writes nothing (found by an outside probe).
  TrainingConfig no_sample = settingsFor(1);
  no_sample.min_overlap = 0.999;
  no_sample.max_overlap = 1.0;
  EXPECT_EQ(train("--config " + config(toJson(no_sample).dump()) + " --out " + run.string()), 2) << output();
  EXPECT_TRUE(contains("overlap in [0.999, 1]")) << output();
  EXPECT_FALSE(fs::exists(run));

  // A field no flag set is named with its source, and says what to do.
  EXPECT_EQ(train("--out " + run.string() + " --steps 1"), 2) << output();
  EXPECT_TRUE(contains("error: command line: field 'warmup_steps': must be at most steps (1), got 50, the default"))
      << output();
  EXPECT_FALSE(fs::exists(run));
}

// A resume asked to stop before the run's step named the config field ('steps') where the user
// gave --steps.
TEST_F(TrainCommandInput, ResumeBelowTheRunsStepNamesTheFlagOrTheConfig) {
  TrainingConfig settings = settingsFor(2);
  settings.checkpoint_every = 2;
  const fs::path run = root_ / "run";
  const std::string two_steps = config(toJson(settings).dump());
  ASSERT_EQ(train("--config " + two_steps + " --out " + run.string()), 0) << output();
  EXPECT_EQ(train("--config " + two_steps + " --out " + run.string() + " --resume --steps 1"), 2) << output();
  EXPECT_TRUE(contains("error: --steps: 1, but the run in " + run.string() +
                       " is already at step 2; ask for more steps to continue it"))
      << output();
  settings.steps = 1;
  const std::string one_step = config(toJson(settings).dump());
  EXPECT_EQ(train("--config " + one_step + " --out " + run.string() + " --resume"), 2) << output();
  EXPECT_TRUE(contains("error: " + one_step + " with the command line: field 'steps': 1, but the run in"))
      << output();
}

// learning_rate 1 with full weight decay and no clipping diverges within a few steps (at step 2
// on our machines; the first step's loss is the initial model's, always finite): the run stops
// there with exit 2 and the previous step's checkpoint stays, where a run that carried on wrote
// NaN checkpoints and rotated the good one out.
TEST_F(TrainCommandInput, StopsAtTheFirstNonFiniteLossAndKeepsTheLastCheckpoint) {
  TrainingConfig settings = settingsFor(6);
  settings.learning_rate = 1;
  settings.min_learning_rate = 0;
  settings.weight_decay = 1;
  settings.clip_grad_norm = 0;
  settings.log_every = 1;
  settings.checkpoint_every = 1;
  settings.keep_checkpoints = 1;
  const fs::path run = root_ / "run";
  EXPECT_EQ(train("--config " + config(toJson(settings).dump()) + " --out " + run.string()), 2) << output();
  const std::string text = output();
  const std::string prefix = "error: training step ";
  const size_t at = text.find(prefix);
  ASSERT_NE(at, std::string::npos) << text;
  const int64_t step = std::stoll(text.substr(at + prefix.size()));
  EXPECT_GE(step, 2);
  EXPECT_TRUE(contains("the run diverged and stops here, without a checkpoint of this state; try a lower "
                       "learning_rate (now 1)")) << text;
  char expected[32];
  std::snprintf(expected, sizeof(expected), "step_%08lld", static_cast<long long>(step - 1));
  std::ifstream latest(run / "checkpoints" / "latest");
  std::string name;
  std::getline(latest, name);
  EXPECT_EQ(name, expected);
  EXPECT_TRUE(fs::exists(run / "checkpoints" / name / "model.safetensors"));
}

// Found by an outside probe: checkpoints were written only on log steps (checkpoint_every 3 with
// log_every 5 wrote none before the end), and a resume appended the rows logged after its
// checkpoint a second time.
TEST_F(TrainCommandInput, CheckpointsFollowTheirOwnIntervalAndAResumedLogHoldsEachStepOnce) {
  TrainingConfig settings = settingsFor(5);
  settings.checkpoint_every = 3;
  settings.log_every = 5;
  settings.keep_checkpoints = 10;
  const fs::path run = root_ / "run";
  ASSERT_EQ(train("--config " + config(toJson(settings).dump()) + " --out " + run.string()), 0) << output();
  EXPECT_TRUE(fs::exists(run / "checkpoints" / "step_00000003" / "model.safetensors"));
  EXPECT_TRUE(fs::exists(run / "checkpoints" / "step_00000005" / "model.safetensors"));

  // As a run killed after logging step 5 but before checkpointing it: its latest is step 3.
  std::ofstream(run / "checkpoints" / "latest") << "step_00000003\n";
  settings.steps = 6;
  settings.log_every = 1;
  ASSERT_EQ(train("--config " + config(toJson(settings).dump()) + " --out " + run.string() + " --resume"), 0)
      << output();
  std::ifstream log(run / "log.csv");
  std::string row;
  std::getline(log, row);  // the header
  std::vector<long long> steps;
  while (std::getline(log, row)) steps.push_back(std::stoll(row));
  EXPECT_EQ(steps, (std::vector<long long>{4, 5, 6})) << "each step once, in order";
}

// Found by an outside probe: a run folder whose first checkpoint was never named (no `latest`)
// was taken by a new run, which deleted the earlier checkpoints and rewrote the log; so was a
// folder holding only a log of steps. A file named checkpoints ended the run after its training
// in an internal error; a folder named config.json kept the settings from being written, silently.
TEST_F(TrainCommandInput, AnEarlierRunsCheckpointsAndLogAreNeverTakenByANewRun) {
  const std::string two_steps = config(toJson(settingsFor(2)).dump());
  const fs::path run = root_ / "run";
  ASSERT_EQ(train("--config " + two_steps + " --out " + run.string()), 0) << output();
  fs::remove(run / "checkpoints" / "latest");
  const auto log_before = fs::file_size(run / "log.csv");
  EXPECT_EQ(train("--config " + two_steps + " --out " + run.string()), 2) << output();
  EXPECT_TRUE(contains("error: " + run.string() + ": already holds a training run (checkpoints); pass --resume"))
      << output();
  EXPECT_EQ(train("--config " + two_steps + " --out " + run.string() + " --resume"), 2) << output();
  EXPECT_TRUE(contains((run / "checkpoints" / "latest").string() + ": missing, so no checkpoint is named to resume "
                       "from, but step_00000002 is there")) << output();
  EXPECT_TRUE(fs::exists(run / "checkpoints" / "step_00000002" / "model.safetensors"));
  EXPECT_EQ(fs::file_size(run / "log.csv"), log_before);

  fs::remove_all(run / "checkpoints");
  fs::remove(run / "config.json");
  EXPECT_EQ(train("--config " + two_steps + " --out " + run.string()), 2) << output();
  // Refused as a new run ("pass --resume") and as a resumed one ("no checkpoint"), neither saying
  // how to go on.
  EXPECT_TRUE(contains("already holds a run that stopped before its first checkpoint (steps in log.csv, nothing to "
                       "resume): choose another --out, or remove log.csv to start over here"))
      << output();
  EXPECT_EQ(train("--config " + two_steps + " --out " + run.string() + " --resume"), 2) << output();
  EXPECT_TRUE(contains("error: " + run.string() + ": holds a run that stopped before its first checkpoint")) << output();
  EXPECT_EQ(fs::file_size(run / "log.csv"), log_before);
  // A log of its header alone holds nothing: a run refused after writing it may start again.
  {
    std::ifstream in(run / "log.csv");
    std::string header;
    std::getline(in, header);
    std::ofstream(run / "log.csv", std::ios::trunc) << header << "\n";
  }
  EXPECT_EQ(train("--config " + two_steps + " --out " + run.string()), 0) << output();

  const fs::path odd = root_ / "odd";
  fs::create_directories(odd);
  std::ofstream(odd / "checkpoints") << "x\n";
  EXPECT_EQ(train("--config " + two_steps + " --out " + odd.string()), 2) << output();
  EXPECT_TRUE(contains("error: " + (odd / "checkpoints").string() + ": exists and is not a folder")) << output();
  fs::remove(odd / "checkpoints");
  fs::create_directories(odd / "config.json");
  EXPECT_EQ(train("--config " + two_steps + " --out " + odd.string()), 2) << output();
  EXPECT_TRUE(contains("error: " + (odd / "config.json").string() + ": exists and is not a file")) << output();
  EXPECT_FALSE(fs::exists(odd / "log.csv"));
  fs::remove(odd / "config.json");
  fs::create_directories(odd / ".run.lock");  // the message named odd/run, which is not there
  EXPECT_EQ(train("--config " + two_steps + " --out " + odd.string()), 2) << output();
  EXPECT_TRUE(contains("error: " + (odd / ".run.lock").string() + ": exists and is not a file")) << output();
  fs::remove(odd / ".run.lock");

  // `--out /` or a dataset's folder took the run in among other files (found by an outside probe).
  std::ofstream(odd / "notes.txt") << "mine\n";
  EXPECT_EQ(train("--config " + two_steps + " --out " + odd.string()), 2) << output();
  EXPECT_TRUE(contains("error: --out: '" + odd.string() + "' holds other files ('notes.txt', ...)")) << output();
  EXPECT_FALSE(fs::exists(odd / "log.csv"));
  const fs::path inside = testing::smallScene().root / "run";
  EXPECT_EQ(train("--config " + two_steps + " --out " + inside.string()), 2) << output();
  EXPECT_TRUE(contains("error: --out: '" + inside.string() + "' is inside the dataset")) << output();
  EXPECT_FALSE(fs::exists(inside));
}

// --resume without --config took the defaults, which a run of other settings refused
// ("warmup_steps ... got 50, the default"): the run's own config.json is the base now.
TEST_F(TrainCommandInput, AResumeWithoutAConfigContinuesWithTheRunsOwnSettings) {
  const fs::path run = root_ / "run";
  ASSERT_EQ(train("--config " + config(toJson(settingsFor(2)).dump()) + " --out " + run.string()), 0) << output();
  ASSERT_EQ(train("--out " + run.string() + " --resume --steps 3"), 0) << output();
  EXPECT_TRUE(fs::exists(run / "checkpoints" / "step_00000003" / "model.safetensors")) << output();
  // A flag still overrides them, and a change the optimisation depends on is still refused.
  EXPECT_EQ(train("--out " + run.string() + " --resume --steps 4 --lr 0.5"), 2) << output();
  EXPECT_TRUE(contains("field 'learning_rate': the checkpoint was trained with 0.001, the resumed run asks for 0.5"))
      << output();
  // Without the run's config.json the defaults stood in, and their first difference was reported.
  fs::remove(run / "config.json");
  EXPECT_EQ(train("--out " + run.string() + " --resume --steps 4"), 2) << output();
  EXPECT_TRUE(contains("error: " + (run / "config.json").string() + ": missing, so the run's settings are unknown"))
      << output();
}

// A run of one rank ran one more step after the one that spent its --max-seconds (found by an
// outside probe: a budget of 0.001 s trained two steps). Under --quiet a run cut short said
// nothing and exited 0, as a finished one does (another probe).
TEST_F(TrainCommandInput, OneRankStopsAfterTheStepThatSpentTheBudgetAndSaysSo) {
  const fs::path run = root_ / "run";
  ASSERT_EQ(train("--config " + config(toJson(settingsFor(5)).dump()) + " --out " + run.string() +
                  " --max-seconds 0.001"),
            0)
      << output();
  EXPECT_TRUE(fs::exists(run / "checkpoints" / "step_00000001" / "model.safetensors")) << output();
  EXPECT_FALSE(fs::exists(run / "checkpoints" / "step_00000002")) << output();
  EXPECT_EQ(output(), "time budget of 0.001 s spent at step 1 of 5; --resume continues from this checkpoint\n");
}

// A fine-tune whose config left long_side at its default trained at another image size than the
// model had learned, without a word (found by an outside probe).
TEST_F(TrainCommandInput, AFineTuneAtAnotherImageSizeSaysSo) {
  const TrainingConfig first = settingsFor(1);
  ASSERT_EQ(train("--config " + config(toJson(first).dump()) + " --out " + (root_ / "first").string()), 0) << output();
  const std::string model = (root_ / "first" / "checkpoints" / "step_00000001" / "model.safetensors").string();
  TrainingConfig larger = first;
  larger.long_side = first.long_side * 2;
  ASSERT_EQ(train("--config " + config(toJson(larger).dump()) + " --model " + model + " --out " +
                  (root_ / "larger").string()),
            0)
      << output();
  EXPECT_TRUE(contains("note: the model learned at long_side " + std::to_string(first.long_side) +
                       "; this run trains at " + std::to_string(larger.long_side)))
      << output();
  ASSERT_EQ(train("--config " + config(toJson(first).dump()) + " --model " + model + " --out " + (root_ / "same").string()),
            0)
      << output();
  EXPECT_FALSE(contains("note: the model learned")) << output();
}

// Validation ran 100000 samples (half an hour) past a spent --max-seconds, before the step's
// checkpoint (found by an outside probe); cut short, it is not logged.
TEST_F(TrainCommandInput, TheTimeBudgetAlsoBoundsValidation) {
  TrainingConfig settings = settingsFor(5);
  settings.validation_every = 1;
  settings.validation_samples = 100000;
  settings.log_every = 1;
  const fs::path run = root_ / "run";
  ASSERT_EQ(train("--config " + config(toJson(settings).dump()) + " --out " + run.string() +
                  " --max-seconds 0.001"),
            0)
      << output();
  EXPECT_TRUE(fs::exists(run / "checkpoints" / "step_00000001" / "model.safetensors")) << output();
  std::ifstream log(run / "log.csv");
  std::string header, row;
  std::getline(log, header);
  std::getline(log, row);
  EXPECT_EQ(row.substr(0, 2), "1,");
  EXPECT_EQ(row.substr(row.size() - 7), ",,,,,,,") << "no validation scores: " << row;
}

// A Ctrl-C or SIGTERM killed the run silently and lost every step since its last checkpoint; now
// the run stops after the step in progress with a checkpoint, and exits 128 + the signal.
TEST_F(TrainCommandInput, ASignalStopsTheRunAfterItsStepWithACheckpoint) {
  TrainingConfig settings = settingsFor(1000000);
  settings.log_every = 1;
  settings.checkpoint_every = 1000000;
  const fs::path run = root_ / "run";
  const std::string settings_file = config(toJson(settings).dump());
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int null = ::open("/dev/null", O_WRONLY);
    ::dup2(null, 1);
    ::dup2(null, 2);
    ::execl(FFLOC_CLI_PATH, FFLOC_CLI_PATH, "train", "--data", testing::smallScene().root.c_str(), "--config",
            settings_file.c_str(), "--out", run.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  // Two logged steps: training is under way.
  for (int waited = 0; waited < 600000; waited += 20) {
    std::ifstream log(run / "log.csv");
    const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
    if (std::count(text.begin(), text.end(), '\n') >= 3) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ::kill(pid, SIGTERM);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 128 + SIGTERM);
  std::ifstream log(run / "log.csv");
  std::string row, last;
  while (std::getline(log, row)) last = row;
  char expected[32];
  std::snprintf(expected, sizeof(expected), "step_%08lld", std::stoll(last));
  std::ifstream latest(run / "checkpoints" / "latest");
  std::string name;
  std::getline(latest, name);
  EXPECT_EQ(name, expected) << "the checkpoint is of the last step logged";
  EXPECT_TRUE(fs::exists(run / "checkpoints" / name / "model.safetensors"));
}

// Validation datasets were read and never sampled under validation_every 0, without a word; a
// validation set too small for a sample was blamed on the training data, naming no folder; one
// sharing frames with the training data was taken as held out.
TEST_F(TrainCommandInput, ValidationDataIsRefusedWhenValidationIsOffOrNotHeldOutAndNamedWhenItFails) {
  const std::string trained = testing::smallScene().root.string();
  // Three frames: too few for a query and its five mapping frames.
  const std::string small = testing::renderTestScene(9, 64, 48, 2, 1).root.string();
  EXPECT_EQ(train("--config " + config(toJson(settingsFor(1)).dump()) + " --out " + (root_ / "a").string() +
                  " --val-data " + small),
            2)
      << output();
  EXPECT_TRUE(contains("error: --val-data: validation is off (validation_every is 0)")) << output();
  EXPECT_FALSE(fs::exists(root_ / "a"));
  TrainingConfig validating = settingsFor(1);
  validating.validation_every = 1;
  validating.validation_samples = 1;
  const std::string validating_config = config(toJson(validating).dump());
  EXPECT_EQ(train("--config " + validating_config + " --out " + (root_ / "b").string() + " --val-data " + trained +
                  "@query"),
            2)
      << output();
  EXPECT_TRUE(contains("error: --val-data: '" + trained + "@query' shares frames with '" + trained +
                       "' of --data, so validation would not be held out"))
      << output();
  EXPECT_EQ(train("--config " + validating_config + " --out " + (root_ / "c").string() + " --val-data " + small), 2)
      << output();
  EXPECT_TRUE(contains("error: validation data (" + small)) << output();
  EXPECT_FALSE(contains("training data")) << output();
}

// Found by an outside probe: two resumes into one run folder at once both wrote it, and an
// optimizer state copied in from another run (another seed, the same step) was taken.
TEST_F(TrainCommandInput, ARunFolderInUseAndAnotherRunsOptimizerStateAreRefused) {
  TrainingConfig settings = settingsFor(2);
  settings.checkpoint_every = 2;
  const fs::path run = root_ / "run", other = root_ / "other";
  const std::string two_steps = config(toJson(settings).dump());
  ASSERT_EQ(train("--config " + two_steps + " --out " + run.string()), 0) << output();
  ASSERT_EQ(train("--config " + two_steps + " --out " + other.string() + " --seed 3"), 0) << output();
  {
    const WriterLock held(run / "run", nullptr);
    EXPECT_EQ(train("--config " + two_steps + " --out " + run.string() + " --resume --steps 3"), 2) << output();
    EXPECT_TRUE(contains("error: --out: '" + run.string() + "' is in use by another 'ffloc train'")) << output();
  }
  const fs::path step = fs::path("checkpoints") / "step_00000002" / "optimizer.safetensors";
  fs::copy_file(other / step, run / step, fs::copy_options::overwrite_existing);
  EXPECT_EQ(train("--config " + two_steps + " --out " + run.string() + " --resume --steps 3"), 2) << output();
  EXPECT_TRUE(contains("optimizer.safetensors: metadata 'training_config': 'seed' is 3 but model.safetensors says 0"))
      << output();
}
#endif

}  // namespace
}  // namespace ffloc
