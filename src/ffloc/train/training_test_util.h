#pragma once

#include <filesystem>
#include <fstream>

#include "ffloc/core/testing/shared_data.h"
#include "ffloc/synthetic/synthetic.h"
#include "ffloc/train/training_config.h"

namespace ffloc::testing {

inline Scene renderTestScene(uint64_t seed, int width, int height, int mapping_frames, int query_frames) {
  SyntheticOptions options;
  options.seed = seed;
  options.width = width;
  options.height = height;
  options.mapping_frames = mapping_frames;
  options.query_frames = query_frames;
  return generateSyntheticScene(options, makeTempDir("ffloc-train-scene"));
}

// One small indoor scene shared by the tests of this binary (rendered once).
inline const Scene& smallScene() {
  static const Scene scene = renderTestScene(5, 128, 96, 12, 2);
  return scene;
}

// A CPU-fast run: the tiny DUSt3R sizes, 128 x 96 images, K = 3.
inline TrainingConfig smallConfig() {
  TrainingConfig config;
  config.model = "random:tiny:7";
  config.mapping_frames = 3;
  config.min_map_tokens = 40;
  config.max_map_tokens = 120;
  config.min_overlap = 0.1;
  config.max_overlap = 0.95;
  config.overlap_candidates = 16;
  config.long_side = 128;
  config.steps = 40;
  config.warmup_steps = 4;
  config.learning_rate = 1e-3;
  config.min_learning_rate = 1e-5;
  config.threads = 1;  // tiny tensors: more threads only add OpenMP spinning
  return config;
}

// smallConfig() for a run of `steps` steps at the full learning rate from the first.
inline TrainingConfig smallConfigOfSteps(int64_t steps) {
  TrainingConfig config = smallConfig();
  config.steps = steps;
  config.warmup_steps = 0;
  return config;
}

// smallConfig() for a short run through the CLI: every step logged, a checkpoint every
// `checkpoint_every` steps, written as JSON to `file`.
inline void writeShortRunConfig(const std::filesystem::path& file, int64_t steps, int64_t checkpoint_every,
                                int keep_checkpoints) {
  TrainingConfig config = smallConfig();
  config.steps = steps;
  config.warmup_steps = 1;
  config.log_every = 1;
  config.checkpoint_every = checkpoint_every;
  config.keep_checkpoints = keep_checkpoints;
  std::ofstream(file) << toJson(config).dump(2);
}

}  // namespace ffloc::testing
