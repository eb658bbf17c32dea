// Files that survive crashes: `ffloc map` and `ffloc train` killed with SIGKILL at random points,
// many times. The previous map or checkpoint must load every time, a new one is complete or
// absent, and a training run killed and resumed again and again ends where a straight run ends.
#include <ATen/ops/equal.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <fcntl.h>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "ffloc/classical/classical_map.h"
#include "ffloc/core/random.h"
#include "ffloc/io/tensor_archive.h"
#include "ffloc/model/model_loader.h"
#include "ffloc/train/training_checkpoint.h"
#include "ffloc/train/training_test_util.h"

#ifdef FFLOC_CLI_PATH
namespace ffloc {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// Runs `ffloc <arguments>` (output discarded); SIGKILL after `kill_after` seconds unless it ended.
// Returns true when the process ended by itself with exit 0.
bool runKilledAfter(const std::vector<std::string>& arguments, double kill_after) {
  std::vector<std::string> all = {FFLOC_CLI_PATH};
  all.insert(all.end(), arguments.begin(), arguments.end());
  std::vector<char*> argv;
  for (std::string& argument : all) argv.push_back(argument.data());
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int null = ::open("/dev/null", O_WRONLY);
    ::dup2(null, 1);
    ::dup2(null, 2);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  const auto deadline = Clock::now() + std::chrono::duration<double>(kill_after);
  int status = 0;
  while (::waitpid(pid, &status, WNOHANG) == 0) {
    if (Clock::now() >= deadline) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      return false;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

double secondsToRun(const std::vector<std::string>& arguments) {
  const auto start = Clock::now();
  EXPECT_TRUE(runKilledAfter(arguments, 600));
  return std::chrono::duration<double>(Clock::now() - start).count();
}

TEST(CrashSafety, AKilledMapWriteLeavesThePreviousMapOrACompleteNewOne) {
  const fs::path dir = testing::makeTempDir("ffloc-crash-map");
  const Scene bigger = testing::renderTestScene(9, 128, 96, 16, 1);
  const fs::path map = dir / "scene.ffmap";
  ASSERT_TRUE(runKilledAfter({"map", "--quiet", "--dataset", testing::smallScene().root.string(), "-o", map.string()}, 600));
  fs::copy_file(map, dir / "previous.ffmap");
  const size_t previous_images = readClassicalMap(map).images.size();
  const std::vector<std::string> rewrite = {"map", "--quiet", "--dataset", bigger.root.string(), "-o", map.string()};
  const double full = secondsToRun(rewrite);
  const size_t new_images = readClassicalMap(map).images.size();
  ASSERT_NE(previous_images, new_images);

  Rng rng(17);
  int kept_previous = 0, completed = 0;
  for (int attempt = 0; attempt < 12; ++attempt) {
    fs::copy_file(dir / "previous.ffmap", map, fs::copy_options::overwrite_existing);
    runKilledAfter(rewrite, rng.uniform(0.3, 1.1) * full);
    const size_t images = readClassicalMap(map).images.size();  // throws, failing the test, if broken
    EXPECT_TRUE(images == previous_images || images == new_images) << images;
    (images == previous_images ? kept_previous : completed)++;
  }
  std::printf("killed map writes: %d left the previous map, %d the complete new one\n", kept_previous, completed);
  fs::remove_all(dir);
}

TEST(CrashSafety, TrainingKilledAndResumedManyTimesEndsAsAStraightRun) {
  const fs::path dir = testing::makeTempDir("ffloc-crash-train");
  testing::writeShortRunConfig(dir / "config.json", 16, 1, 2);
  const auto train = [&](const std::string& out, bool resume) {
    std::vector<std::string> arguments = {"train", "--quiet", "--config", (dir / "config.json").string(), "--data",
                                          testing::smallScene().root.string(), "--out", (dir / out).string()};
    if (resume) arguments.push_back("--resume");
    return arguments;
  };
  const double full = secondsToRun(train("straight", false));

  Rng rng(23);
  int kills = 0;
  bool finished = false;
  for (int attempt = 0; attempt < 40 && !finished; ++attempt) {
    const bool resume = latestTrainingCheckpoint(dir / "killed").has_value();
    // Late enough into a run to pass model loading and write some checkpoints.
    finished = runKilledAfter(train("killed", resume), kills < 8 ? rng.uniform(0.15, 0.5) * full : 600);
    if (!finished) ++kills;
    const auto checkpoint = latestTrainingCheckpoint(dir / "killed");
    if (!checkpoint) continue;
    // Whatever `latest` names is complete: both files open and the weights load as a model.
    EXPECT_NO_THROW(openTensorArchive(checkpoint->folder / "optimizer.safetensors")) << checkpoint->folder;
    EXPECT_NO_THROW(loadModel((checkpoint->folder / "model.safetensors").string())) << checkpoint->folder;
  }
  ASSERT_TRUE(finished);
  std::printf("training killed %d times and resumed each time\n", kills);
  EXPECT_GE(kills, 1);

  const auto weights = [&](const std::string& out) {
    LoadedModel model = loadModel((dir / out / "checkpoints" / "step_00000016" / "model.safetensors").string());
    std::vector<at::Tensor> tensors;
    const ParameterTable table = model.model->parameterTable();
    for (const auto& entry : table.entries()) tensors.push_back(entry.tensor->clone());
    return tensors;
  };
  const std::vector<at::Tensor> straight = weights("straight"), killed = weights("killed");
  ASSERT_EQ(straight.size(), killed.size());
  for (size_t i = 0; i < straight.size(); ++i) EXPECT_TRUE(at::equal(straight[i], killed[i])) << "tensor " << i;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace ffloc
#endif
