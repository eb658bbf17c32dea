#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "ffloc/core/random.h"
#include "ffloc/data/scene.h"
#include "ffloc/geometry/preprocess.h"
#include "ffloc/geometry/normalization.h"
#include "ffloc/io/image.h"
#include "ffloc/model/map_assembly.h"

namespace ffloc {

struct SampleOptions {
  int mapping_frames = 5;  // K
  int min_map_tokens = 250;
  int max_map_tokens = 1000;
  double min_overlap = 0.2;  // pairOverlap(query, mapping) range (paper appendix)
  double max_overlap = 0.85;
  int overlap_candidates = 64;
  int overlap_stride = 4;
  int long_side = 512;
  int patch_size = 16;
  double colour_jitter = 0.0;
  int max_attempts = 32;  // random queries tried before every frame is tried in turn
};

// One training example (paper, section 3 "Training" and appendix): a query with depth, K mapping
// images that overlap it, the map tokens to sample from them, and ground truth in the scene
// frame normalised by the mapping poses (first mapping image as P_0).
struct TrainingSample {
  at::Tensor query_image;                   // (1, 3, H, W) float32 in [-1, 1]
  std::vector<at::Tensor> mapping_images;   // K x (1, 3, H_k, W_k)
  MapLayout layout;                         // normalisation, rays of the patch centres, sampled tokens
  at::Tensor query_points;                  // (1, H, W, 3) float32, normalised frame; 0 where invalid
  at::Tensor query_valid;                   // (1, H, W) bool, pixels with depth
  at::Tensor map_points;                    // (1, N, 3) float32, the tokens' patch-centre points
  at::Tensor map_valid;                     // (1, N) bool
  Intrinsics query_camera;  // of the preprocessed query image
  Pose query_pose;          // camera-to-world, in the dataset's world frame
  std::string scene;
  std::string query;
  std::vector<std::string> mapping;
  std::vector<double> overlaps;             // of each mapping image with the query
};

// Draws training samples from posed RGB-D scenes. A draw is a pure function of its seed (the
// frame choice, token count and sample, augmentation), so a run can be replayed or resumed from
// the step number alone. Preprocessed frames and pair overlaps are cached in memory as they are
// first needed.
class TrainingSampler {
 public:
  // InputError when no scene has a frame with depth, or a frame has lens distortion. `name`
  // ("training data", "validation data") and the scenes' folders begin the errors of its draws.
  TrainingSampler(std::vector<Scene> scenes, const SampleOptions& options, std::string name = "training data");

  // The sample of `seed` with `map_tokens` map tokens (at most all of the mapping images'). Safe to
  // call from several threads. When options.max_attempts random queries fail, every frame is tried
  // as the query; InputError naming the scenes when none has K overlapping mapping frames.
  TrainingSample sample(uint64_t seed, int64_t map_tokens);
  // A map token count in [min_map_tokens, max_map_tokens] drawn from `seed`: samples that share a
  // forward pass share it (trainer.h).
  int64_t mapTokenCount(uint64_t seed) const;

  const std::vector<Scene>& scenes() const { return scenes_; }

 private:
  // "training data (a, b)": what the sampler draws from, for its errors.
  std::string source() const;

  struct PreparedFrame {
    cv::Mat rgb;          // preprocessed uint8 RGB
    Frame frame;          // intrinsics of the preprocessed image
    cv::Mat1f depth;      // at the preprocessed resolution (nearest), 0 = invalid
  };
  const PreparedFrame& prepared(size_t scene, size_t frame);
  double overlap(size_t scene, size_t a, size_t b);
  // A query and the first options.mapping_frames of its overlap candidates (drawn from `rng`)
  // whose overlap lies in the bounds; none when too few do.
  struct Draw {
    size_t scene, query;
    std::vector<size_t> mapping;
    std::vector<double> overlaps;
  };
  std::optional<Draw> tryQuery(size_t scene, size_t query, Rng& rng);

  std::vector<Scene> scenes_;
  SampleOptions options_;
  std::string name_;
  std::vector<std::vector<size_t>> frames_with_depth_;
  std::mutex cache_mutex_;  // guards the two caches
  std::map<std::pair<size_t, size_t>, std::unique_ptr<PreparedFrame>> prepared_;
  std::map<std::tuple<size_t, size_t, size_t>, double> overlaps_;
};

}  // namespace ffloc
