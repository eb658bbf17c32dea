#pragma once

#include "ffloc/core/testing/shared_data.h"
#include "ffloc/synthetic/synthetic.h"
#include "ffloc/train/training_config.h"

namespace ffloc::testing {

// One small indoor scene shared by the tests of this binary (rendered once).
inline const Scene& smallScene() {
  static const Scene scene = [] {
    SyntheticOptions options;
    options.seed = 5;
    options.width = 128;
    options.height = 96;
    options.mapping_frames = 12;
    options.query_frames = 2;
    return generateSyntheticScene(options, makeTempDir("ffloc-train-scene"));
  }();
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

}  // namespace ffloc::testing
