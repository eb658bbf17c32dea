#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <vector>

#include "ffloc/io/tensor_archive.h"
#include "ffloc/model/dust3r_model.h"
#include "ffloc/model/ray_encoding.h"

namespace ffloc {

// FastForward (paper, section 3): the query image and a map of N tokens sampled from K mapping
// images go through DUSt3R's two-branch decoder; the query branch (dec_blocks) feeds a DPT head
// that predicts query 3D coordinates in the normalised scene, the map branch (dec_blocks2) a
// one-layer head that predicts the map tokens' coordinates (a training signal).
struct FastForwardConfig {
  Dust3rConfig dust3r;
  RayEncoderConfig rays;
  // Long side of the images the model was trained on; mapping and localisation preprocess to it
  // unless told otherwise. DUSt3R's 512; a FastForward checkpoint records its own.
  int64_t input_long_side = 512;
};

// N map tokens, each remembering where it came from.
struct MapTokens {
  at::Tensor features;     // (1, N, enc_dim) encoder tokens
  at::Tensor positions;    // (1, N, 2) int64 patch (row, col) in its own image, for RoPE
  at::Tensor rays;         // (1, N, 6) float32 normalised camera origin + viewing direction
  at::Tensor image_index;  // (1, N) int64 index of the mapping image
  at::Tensor token_index;  // (1, N) int64 token index inside that image
};

// `count` distinct (image, token) pairs drawn uniformly from mapping images with the given token
// counts (all of them, in order, when count >= the total), as an (M, 2) int64 tensor. Drawn with
// core/random.h, so the sample is the same on every machine and standard library.
at::Tensor sampleMapTokenIndices(const std::vector<int64_t>& tokens_per_image, int64_t count, uint64_t seed);

// Gathers the map tokens listed in `indices` ((M, 2) image, token) from per-image encodings
// (batch 1) and per-image ray tensors ((1, T_k, 6)). InputError for out-of-range indices or
// inconsistent inputs.
MapTokens gatherMapTokens(const std::vector<Dust3rEncoding>& images, const std::vector<at::Tensor>& rays,
                          const at::Tensor& indices);

struct FastForwardPrediction {
  Dust3rPointMap query;  // (1, H, W, 3) / (1, H, W), normalised scene frame
  Dust3rPointMap map;    // (1, N, 3) / (1, N)
};

class FastForwardModel {
 public:
  explicit FastForwardModel(const FastForwardConfig& config);

  const FastForwardConfig& config() const { return config_; }
  const Dust3rModel& dust3r() const { return dust3r_; }

  // DUSt3R's keys without downstream_head2, plus ray_embed.fc{1,2}.{weight,bias} and
  // map_head.{weight,bias}.
  ParameterTable parameterTable();
  // Strict load of a FastForward checkpoint.
  void loadWeights(const TensorArchive& archive);
  // The paper's initialisation: encoder, decoder and the query DPT head from a DUSt3R checkpoint
  // (its second head is ignored); the ray MLP's first layer and the map head Xavier-uniform with
  // zero biases from `seed`, the ray MLP's last layer zero so that map tokens start as DUSt3R's.
  void initializeFromDust3r(const TensorArchive& dust3r, uint64_t seed = 0);
  // As Dust3rModel::to; the ray MLP follows the backbone dtype, the map head stays float32.
  void to(at::Device device, at::ScalarType backbone_dtype, at::ScalarType head_dtype = at::kFloat);

  // Shared encoder (see Dust3rModel::encode).
  Dust3rEncoding encode(const at::Tensor& images) const { return dust3r_.encode(images); }

  // Trace names: the query is "view1", the map "view2" (DUSt3R's names), plus "map.rays_embed".
  FastForwardPrediction forward(const Dust3rEncoding& query, const MapTokens& map,
                                TensorTrace* trace = nullptr) const;

 private:
  void registerNewParameters(ParameterTable& table);

  FastForwardConfig config_;
  Dust3rModel dust3r_;
  RayEncoder ray_embed_;
  nn::Linear map_head_;
};

}  // namespace ffloc
