// Batches and data-parallel training: a batch's gradient is the mean of its samples' gradients,
// two Gloo ranks reproduce one rank with twice the batch, and a run resumes on another world size.
#include <ATen/TensorOperators.h>
#include <ATen/ops/equal.h>
#include <ATen/ops/ones.h>
#include <ATen/ops/zeros_like.h>
#include <gtest/gtest.h>
#include <future>

#include <sys/wait.h>

#include <cstdlib>
#include <map>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "ffloc/core/error.h"
#include "ffloc/model/model_loader.h"
#include "ffloc/train/data_parallel.h"
#include "ffloc/train/local_launcher.h"
#include "ffloc/train/training_checkpoint.h"
#include "ffloc/train/trainer.h"
#include "ffloc/train/training_test_util.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;
using testing::smallConfig;
using testing::smallScene;

// A second scene whose images preprocess to another size than smallScene's, so that one batch
// needs two forward passes.
const Scene& wideScene() {
  static const Scene scene = testing::renderTestScene(6, 160, 96, 10, 1);
  return scene;
}

std::vector<at::Tensor> gradientSnapshot(Trainer& trainer) {
  std::vector<at::Tensor> out;
  for (const at::Tensor& gradient : gradientsOf(trainer.optimizer().parameters())) out.push_back(gradient.clone());
  return out;
}

void clearGradients(Trainer& trainer) {
  for (const at::Tensor& gradient : gradientsOf(trainer.optimizer().parameters())) gradient.zero_();
}

double relativeDifference(const at::Tensor& a, const at::Tensor& b) {
  const double scale = b.norm().item<double>();
  return (a - b).norm().item<double>() / (scale > 0 ? scale : 1.0);
}

void expectSameTensors(const std::vector<at::Tensor>& a, const std::vector<at::Tensor>& b, double tolerance,
                       const std::string& what) {
  ASSERT_EQ(a.size(), b.size());
  double worst = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    const double difference = relativeDifference(a[i], b[i]);
    worst = std::max(worst, difference);
    EXPECT_LE(difference, tolerance) << what << " tensor " << i;
  }
  std::printf("%s: largest relative difference %.3g over %zu tensors\n", what.c_str(), worst, a.size());
}

TEST(BatchTraining, BatchGradientIsTheMeanOfSingleSampleGradients) {
  const TrainingConfig config = smallConfig();
  Trainer trainer(config, {smallScene(), wideScene()}, testing::makeTempDir("ffloc-batch-gradient"));
  TrainingSampler small({smallScene()}, sampleOptions(config, 16));
  TrainingSampler wide({wideScene()}, sampleOptions(config, 16));
  const int64_t tokens = 90;
  const std::vector<TrainingSample> samples = {small.sample(1, tokens), small.sample(2, tokens),
                                               wide.sample(3, tokens), small.sample(4, tokens)};
  ASSERT_NE(samples[0].query_image.sizes(), samples[2].query_image.sizes());
  const double weight = 1.0 / static_cast<double>(samples.size());

  clearGradients(trainer);
  const BatchLosses batch = trainer.accumulateGradients(samples, weight);
  const std::vector<at::Tensor> batched = gradientSnapshot(trainer);
  clearGradients(trainer);
  double single_loss = 0;
  for (const TrainingSample& sample : samples) single_loss += trainer.accumulateGradients({sample}, weight).loss;
  const std::vector<at::Tensor> singles = gradientSnapshot(trainer);

  EXPECT_EQ(batch.samples, 4);
  EXPECT_NEAR(batch.loss, single_loss, 1e-5 * std::abs(single_loss));
  expectSameTensors(batched, singles, 1e-5, "batch of 4 vs 4 single samples");
}

// Two ranks in two threads of this process, each with its own Gloo process group over loopback.
TEST(DataParallelTraining, TwoRanksAllReduceTheGradientsOfOneRankWithTwiceTheBatch) {
  const TrainingConfig config = smallConfig();
  TrainingSampler sampler({smallScene()}, sampleOptions(config, 16));
  const std::vector<TrainingSample> samples = {sampler.sample(21, 70), sampler.sample(22, 70)};

  Trainer single(config, {smallScene()}, testing::makeTempDir("ffloc-dp-single"));
  clearGradients(single);
  single.accumulateGradients(samples, 0.5);
  const std::vector<at::Tensor> expected = gradientSnapshot(single);

  const int port = freeLoopbackPort();
  std::vector<std::vector<at::Tensor>> reduced(2);
  std::vector<std::string> errors(2);
  std::vector<std::thread> ranks;
  for (int rank = 0; rank < 2; ++rank) {
    ranks.emplace_back([&, rank] {
      try {
        DistributedEnvironment environment;
        environment.rank = environment.local_rank = rank;
        environment.world_size = environment.local_world_size = 2;
        environment.master_port = port;
        DataParallel parallel(environment, /*cuda=*/false, /*rendezvous_timeout_s=*/120);
        Trainer trainer(config, {smallScene()}, testing::makeTempDir("ffloc-dp-rank"), false, {}, &parallel);
        clearGradients(trainer);
        trainer.accumulateGradients({samples[static_cast<size_t>(rank)]}, 0.5);
        parallel.allReduceSum(gradientsOf(trainer.optimizer().parameters()), /*bucket_bytes=*/1 << 16);
        reduced[static_cast<size_t>(rank)] = gradientSnapshot(trainer);
      } catch (const std::exception& e) {
        errors[static_cast<size_t>(rank)] = e.what();
      }
    });
  }
  for (std::thread& rank : ranks) rank.join();
  ASSERT_EQ(errors[0], "");
  ASSERT_EQ(errors[1], "");
  expectSameTensors(reduced[0], expected, 1e-5, "rank 0 all-reduced vs one rank of batch 2");
  expectSameTensors(reduced[1], reduced[0], 0.0, "rank 1 vs rank 0");
}

// A rank that stopped failed the others' next collective with gloo's own words, reported as an
// internal error (found by an outside probe).
TEST(DataParallelTraining, ACollectiveWithARankGoneSaysSo) {
  const int port = freeLoopbackPort();
  std::promise<void> rank_one_gone;
  std::string error_of_rank_zero;
  std::thread rank_one([&] {
    DistributedEnvironment environment;
    environment.rank = environment.local_rank = 1;
    environment.world_size = environment.local_world_size = 2;
    environment.master_port = port;
    { DataParallel parallel(environment, /*cuda=*/false, /*rendezvous_timeout_s=*/60, /*collective_timeout_s=*/10); }
    rank_one_gone.set_value();
  });
  try {
    DistributedEnvironment environment;
    environment.world_size = environment.local_world_size = 2;
    environment.master_port = port;
    DataParallel parallel(environment, /*cuda=*/false, /*rendezvous_timeout_s=*/60, /*collective_timeout_s=*/10);
    rank_one_gone.get_future().wait();
    parallel.allReduceSum({at::ones({4})});
  } catch (const InputError& e) {
    error_of_rank_zero = e.what();
  }
  rank_one.join();
  EXPECT_NE(error_of_rank_zero.find("rank 0: all-reduce failed: another rank stopped or lost its connection"),
            std::string::npos)
      << error_of_rank_zero;
}

// A MASTER_ADDR that resolves to nothing was reported as the rendezvous timing out, after it.
TEST(DataParallelTraining, AMasterAddressThatDoesNotResolveIsNamedAtOnce) {
  DistributedEnvironment environment;
  environment.world_size = environment.local_world_size = 2;
  environment.master_addr = "no-such-host.invalid";  // RFC 2606: never resolves
  environment.master_port = freeLoopbackPort();
  try {
    DataParallel parallel(environment, /*cuda=*/false, /*rendezvous_timeout_s=*/30);
    ADD_FAILURE() << "joined";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("MASTER_ADDR: 'no-such-host.invalid' does not resolve: ", 0), 0u) << e.what();
  }
}

TEST(DataParallelTraining, EnvironmentIsReadAsTorchrunWritesIt) {
  ::setenv("WORLD_SIZE", "4", 1);
  ::setenv("RANK", "3", 1);
  ::setenv("LOCAL_WORLD_SIZE", "2", 1);
  ::setenv("LOCAL_RANK", "1", 1);
  ::setenv("MASTER_ADDR", "node0", 1);
  ::setenv("MASTER_PORT", "29611", 1);
  const DistributedEnvironment environment = DistributedEnvironment::fromProcessEnvironment();
  EXPECT_EQ(environment.rank, 3);
  EXPECT_EQ(environment.world_size, 4);
  EXPECT_EQ(environment.local_rank, 1);
  EXPECT_EQ(environment.local_world_size, 2);
  EXPECT_EQ(environment.master_addr, "node0");
  EXPECT_EQ(environment.master_port, 29611);
  ::setenv("RANK", "4", 1);
  try {
    DistributedEnvironment::fromProcessEnvironment();
    ADD_FAILURE() << "RANK 4 of 4 was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("RANK"), std::string::npos) << e.what();
  }
  for (const char* name : {"WORLD_SIZE", "RANK", "LOCAL_WORLD_SIZE", "LOCAL_RANK", "MASTER_ADDR", "MASTER_PORT"}) {
    ::unsetenv(name);
  }
  EXPECT_FALSE(DistributedEnvironment::fromProcessEnvironment().distributed());
}

#ifdef FFLOC_CLI_PATH
// The CLI end to end: `ffloc train --nproc-per-node 2` starts two ranks the way torchrun would.
class TrainCommandRanks : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = testing::makeTempDir("ffloc-train-cli");
    testing::writeShortRunConfig(root_ / "config.json", 4, 2, 5);
  }

  static int train(const std::string& out, const std::string& extra) {
    const std::string command = std::string(FFLOC_CLI_PATH) + " train --quiet --config " + (root_ / "config.json").string() +
                                " --data " + smallScene().root.string() + " --out " + (root_ / out).string() + " " +
                                extra + " > " + (root_ / (out + ".log")).string() + " 2>&1";
    const int status = std::system(command.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  // `ffloc train --nproc-per-node 2` on a long run into the folder `name`.
  static std::string launcherCommand(const std::string& name) {
    return std::string(FFLOC_CLI_PATH) + " train --config " + (root_ / "long.json").string() + " --data " +
           smallScene().root.string() + " --out " + (root_ / name).string() + " --nproc-per-node 2";
  }

  // Starts launcherCommand(name), sends SIGTERM to `target` (shell, $launcher the launcher's pid)
  // once a step is logged (every rank is then training; a fixed 4 s sometimes caught a loaded
  // machine's rank still joining), waits for the launcher (its exit code to <out>.rc, its output
  // to <out>.log), runs the shell `then`; returns the run folder <out>.
  static std::string stopLauncherWhileTraining(const std::string& name, const std::string& target,
                                               const std::string& then = "") {
    testing::writeShortRunConfig(root_ / "long.json", 100000, 100000, 1);
    const std::string out = (root_ / name).string();
    const std::string script = launcherCommand(name) + " > " + out + ".log 2>&1 & launcher=$!; for i in $(seq 500); do " +
                               "[ $(cat " + out + "/log.csv 2>/dev/null | wc -l) -ge 2 ] && break; sleep 0.2; done; " +
                               "kill -TERM " + target + "; wait $launcher; echo $? > " + out + ".rc" + then + "; true";
    EXPECT_EQ(std::system(("timeout 120 /bin/sh -c '" + script + "'").c_str()), 0);
    return out;
  }

  static std::string output(const std::string& out) {
    std::ifstream in(root_ / (out + ".log"));
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
  }

  // step -> loss, from the run's log.csv (a resumed run's later rows win).
  static std::map<int64_t, double> losses(const std::string& out) {
    std::ifstream in(root_ / out / "log.csv");
    std::string line;
    std::getline(in, line);
    std::map<int64_t, double> out_losses;
    while (std::getline(in, line)) {
      std::stringstream row(line);
      std::string step, loss;
      std::getline(row, step, ',');
      std::getline(row, loss, ',');
      out_losses[std::stoll(step)] = std::stod(loss);
    }
    return out_losses;
  }

  static std::vector<at::Tensor> weights(const std::string& out, int64_t step) {
    char folder[32];
    std::snprintf(folder, sizeof(folder), "step_%08lld", static_cast<long long>(step));
    LoadedModel model = loadModel((root_ / out / "checkpoints" / folder / "model.safetensors").string());
    std::vector<at::Tensor> tensors;
    const ParameterTable table = model.model->parameterTable();
    for (const auto& entry : table.entries()) tensors.push_back(entry.tensor->clone());
    return tensors;
  }

  static void expectSameLosses(const std::map<int64_t, double>& a, const std::map<int64_t, double>& b) {
    ASSERT_EQ(a.size(), b.size());
    for (const auto& [step, loss] : b) {
      ASSERT_TRUE(a.count(step)) << "step " << step;
      EXPECT_NEAR(a.at(step), loss, 1e-4 * std::abs(loss)) << "step " << step;
    }
  }

  static fs::path root_;
};

fs::path TrainCommandRanks::root_;

TEST_F(TrainCommandRanks, TwoRanksOfBatchOneTrainAsOneRankOfBatchTwo) {
  ASSERT_EQ(train("one_rank", "--batch-size 2"), 0) << output("one_rank");
  ASSERT_EQ(train("two_ranks", "--batch-size 1 --nproc-per-node 2"), 0) << output("two_ranks");
  const auto straight = losses("one_rank");
  ASSERT_EQ(straight.size(), 4u);
  expectSameLosses(losses("two_ranks"), straight);
  // AdamW may flip the sign of an update whose gradient is at rounding level: compare norms.
  const std::vector<at::Tensor> a = weights("one_rank", 4), b = weights("two_ranks", 4);
  expectSameTensors(b, a, 1e-3, "parameters after 4 steps, 2 ranks x 1 vs 1 rank x 2");

  // Resumed from step 2 on one rank of batch 2: the same global batch, so the same run.
  fs::copy(root_ / "two_ranks", root_ / "resumed", fs::copy_options::recursive);
  std::ofstream(root_ / "resumed" / "checkpoints" / "latest", std::ios::trunc) << "step_00000002\n";
  ASSERT_EQ(train("resumed", "--resume --batch-size 2"), 0) << output("resumed");
  expectSameLosses(losses("resumed"), straight);
  expectSameTensors(weights("resumed", 4), a, 1e-3, "parameters after resuming on another world size");

  // Another global batch is refused, naming the field.
  fs::copy(root_ / "two_ranks", root_ / "refused", fs::copy_options::recursive);
  EXPECT_EQ(train("refused", "--resume --batch-size 1"), 2);
  EXPECT_NE(output("refused").find("batch_size"), std::string::npos) << output("refused");
}

// Found by an outside probe: ranks started with different settings (rank 1 given --lr 5e-4)
// trained apart without a word, and a rank whose peer never started waited an hour in silence.
TEST_F(TrainCommandRanks, RanksOfOtherSettingsAreRefusedAndAMissingRankIsWaitedForAsLongAsAsked) {
  const int port = freeLoopbackPort();
  const auto rankCommand = [&](int rank, const std::string& out, const std::string& extra) {
    return "RANK=" + std::to_string(rank) + " LOCAL_RANK=" + std::to_string(rank) +
           " WORLD_SIZE=2 LOCAL_WORLD_SIZE=2 MASTER_ADDR=127.0.0.1 MASTER_PORT=" + std::to_string(port) + " " +
           FFLOC_CLI_PATH + " train --quiet --rendezvous-timeout 60 --config " + (root_ / "config.json").string() +
           " --data " + smallScene().root.string() + " --out " + (root_ / out).string() + " " + extra + " > " +
           (root_ / (out + std::to_string(rank) + ".log")).string() + " 2>&1; echo $? > " +
           (root_ / (out + std::to_string(rank) + ".rc")).string();
  };
  const std::string both = "(" + rankCommand(0, "apart", "") + ") & (" + rankCommand(1, "apart", "--lr 5e-4") + ") & wait";
  ASSERT_EQ(std::system(("/bin/sh -c '" + both + "'").c_str()), 0);
  for (int rank = 0; rank < 2; ++rank) {
    std::ifstream code(root_ / ("apart" + std::to_string(rank) + ".rc"));
    int exit_code = -1;
    code >> exit_code;
    const std::string log = output("apart" + std::to_string(rank));
    EXPECT_EQ(exit_code, 2) << log;
    EXPECT_NE(log.find("rank " + std::to_string(rank) + ": the ranks were started with different settings"),
              std::string::npos)
        << log;
  }
  EXPECT_NE(output("apart1").find("field 'learning_rate' is 0.0005 here but"), std::string::npos) << output("apart1");

  const auto started = std::chrono::steady_clock::now();
  const std::string alone = rankCommand(0, "alone", "").replace(rankCommand(0, "alone", "").find("--rendezvous-timeout 60"),
                                                                 23, "--rendezvous-timeout 2");
  ASSERT_EQ(std::system(("/bin/sh -c '" + alone + "'").c_str()), 0);
  const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  std::ifstream code(root_ / "alone0.rc");
  int exit_code = -1;
  code >> exit_code;
  EXPECT_EQ(exit_code, 2) << output("alone0");
  EXPECT_NE(output("alone0").find("rank 0 of 2: only 1 of 2 ranks joined within 2 s"), std::string::npos)
      << output("alone0");
  EXPECT_LT(waited, 60);

  // A second process given RANK=1 joined, then waited for ever, whatever --rendezvous-timeout said.
  const std::string three = "(" + rankCommand(0, "dup", "") + ") & (" + rankCommand(1, "dup", "") + ") & (" +
                            rankCommand(1, "dup_again", "") + ") & wait";
  ASSERT_EQ(std::system(("timeout 120 /bin/sh -c '" + three + "'").c_str()), 0);
  int refused = 0;
  for (const std::string run : {"dup1", "dup_again1"}) {
    std::ifstream rank_code(root_ / (run + ".rc"));
    int code_of_rank = -1;
    rank_code >> code_of_rank;
    if (code_of_rank == 0) continue;
    EXPECT_EQ(code_of_rank, 2) << output(run);
    EXPECT_NE(output(run).find("another process has already joined as this rank (two processes were given RANK=1)"),
              std::string::npos)
        << output(run);
    ++refused;
  }
  EXPECT_EQ(refused, 1) << output("dup1") << output("dup_again1");
}

// Found by an outside probe: `kill` of the --nproc-per-node launcher (as a scheduler stops a job)
// ended it alone, and its ranks trained on as orphans.
TEST_F(TrainCommandRanks, StoppingTheLauncherStopsItsRanks) {
  const std::string out = stopLauncherWhileTraining("stopped", "$launcher", "; sleep 2; pgrep -f \"^" +
                                                                                  launcherCommand("stopped") + "\" > " +
                                                                                  (root_ / "stopped").string() + ".left");
  std::ifstream code(out + ".rc");
  int exit_code = -1;
  code >> exit_code;
  EXPECT_EQ(exit_code, 128 + SIGTERM) << output("stopped");
  std::ifstream left(out + ".left");
  const std::string orphans((std::istreambuf_iterator<char>(left)), {});
  EXPECT_EQ(orphans, "") << "ranks left running: " << orphans;
  // The ranks stop after one step with a checkpoint, as one rank does: the launcher no longer
  // sends a second SIGTERM on, which ended rank 0 in the middle of writing it.
  const auto checkpoint = latestTrainingCheckpoint(out);
  ASSERT_TRUE(checkpoint) << output("stopped");
  EXPECT_TRUE(fs::exists(checkpoint->folder / "model.safetensors")) << output("stopped");
}

// A rank stopped by a signal sent to it alone ends after a step the others agree on: it was
// reported as "failed" and the others were sent SIGTERM.
TEST_F(TrainCommandRanks, ARankStoppedBySignalIsSaidSoAndTheOthersStopWithIt) {
  const std::string out = stopLauncherWhileTraining("one", "$(pgrep -P $launcher | tail -1)");
  const std::string text = output("one");
  EXPECT_NE(text.find("rank 1 stopped by signal 15 (Terminated); the other ranks stop at the same step"), std::string::npos)
      << text;
  EXPECT_EQ(text.find("failed"), std::string::npos) << text;
  const auto checkpoint = latestTrainingCheckpoint(out);
  ASSERT_TRUE(checkpoint) << text;
  EXPECT_TRUE(fs::exists(checkpoint->folder / "model.safetensors")) << text;
}
#endif

}  // namespace
}  // namespace ffloc
