#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <vector>

#include "ffloc/io/tensor_archive.h"
#include "ffloc/model/dust3r_model.h"
#include "ffloc/model/fastforward_config.h"
#include "ffloc/model/matching_head.h"
#include "ffloc/model/point_encoding.h"
#include "ffloc/model/ray_encoding.h"

namespace ffloc {

// FastForward (paper, section 3): the query image and a map of N tokens sampled from K mapping
// images go through DUSt3R's two-branch decoder; the query branch (dec_blocks) feeds the query
// head (DPT, or the matching head of fastforward_config.h) that predicts query 3D coordinates in
// the normalised scene, the map branch (dec_blocks2) a one-layer head that predicts the map
// tokens' coordinates (a training signal).

// What FastForwardModel::forward computes: both heads (training, traces), or the query's points
// alone (localisation). For the query alone, a matching head that does not read the decoder's
// outputs (MatchingHead::readsDecoderOutput, the untrained model) lets the decoder be skipped:
// the same points, without the network's cost.
enum class FastForwardOutputs { kQueryAndMap, kQuery };

// N map tokens, each remembering where it came from.
struct MapTokens {
  at::Tensor features;     // (1, N, enc_dim) encoder tokens
  at::Tensor positions;    // (1, N, 2) int64 patch (row, col) in its own image, for RoPE
  at::Tensor rays;         // (1, N, 6) float32 normalised camera origin + viewing direction
  at::Tensor image_index;  // (1, N) int64 index of the mapping image
  at::Tensor token_index;  // (1, N) int64 token index inside that image
  // The token's 3D point in the normalised frame where its mapping frame had one (depth or a
  // triangulated point), for models with a point encoder or a matching head; else undefined.
  at::Tensor points;       // (1, N, 3) float32, 0 where none
  at::Tensor point_valid;  // (1, N) bool
};

// `count` distinct (image, token) pairs drawn uniformly from mapping images with the given token
// counts (all of them, in order, when count >= the total), as an (M, 2) int64 tensor. Drawn with
// core/random.h, so the sample is the same on every machine and standard library.
at::Tensor sampleMapTokenIndices(const std::vector<int64_t>& tokens_per_image, int64_t count, uint64_t seed);

// Gathers the map tokens listed in `indices` ((M, 2) image, token) from per-image encodings
// (batch 1), per-image ray tensors ((1, T_k, 6)) and, when given, per-image point tensors
// ((1, T_k, 3) normalised, non-finite where a token has no point). InputError for out-of-range
// indices or inconsistent inputs.
MapTokens gatherMapTokens(const std::vector<Dust3rEncoding>& images, const std::vector<at::Tensor>& rays,
                          const at::Tensor& indices, const std::vector<at::Tensor>& points = {});

struct FastForwardPrediction {
  Dust3rPointMap query;  // (1, H, W, 3) / (1, H, W), normalised scene frame
  Dust3rPointMap map;    // (1, N, 3) / (1, N); undefined when only the query was asked for
  at::Tensor match_logits;  // the matching head's (B, T_query, N + 1) logits; undefined for DPT
};

class FastForwardModel {
 public:
  explicit FastForwardModel(const FastForwardConfig& config);

  const FastForwardConfig& config() const { return config_; }
  // The image size mapping and localisation preprocess to (config().input_long_side).
  void setInputLongSide(int64_t long_side) { config_.input_long_side = long_side; }
  const Dust3rModel& dust3r() const { return dust3r_; }

  // DUSt3R's keys without downstream_head2, plus ray_embed.fc{1,2}.{weight,bias} and
  // map_head.{weight,bias}; with the dense-sift encoder no encoder keys, with a point encoder
  // point_embed.fc{1,2}.*, with the matching head match_head.* instead of downstream_head1.
  ParameterTable parameterTable();
  // Strict load of a FastForward checkpoint.
  void loadWeights(const TensorArchive& archive);
  // The paper's initialisation: encoder, decoder and the query DPT head from a DUSt3R checkpoint
  // (its second head is ignored); the ray MLP's first layer and the map head Xavier-uniform with
  // zero biases from `seed`, the ray MLP's last layer zero so that map tokens start as DUSt3R's.
  void initializeFromDust3r(const TensorArchive& dust3r, uint64_t seed = 0);
  // The matching family's start (matching_head.h): the untrained model is nearest-neighbour
  // matching of its encoder's descriptors. Other parameters keep their values.
  void initializeMatchingHeadAsNearestNeighbour();
  // As Dust3rModel::to; the ray MLP follows the backbone dtype, the map head stays float32.
  void to(at::Device device, at::ScalarType backbone_dtype, at::ScalarType head_dtype = at::kFloat);

  // Shared encoder: DUSt3R's ViT (Dust3rModel::encode) or dense SIFT, in the backbone dtype.
  Dust3rEncoding encode(const at::Tensor& images) const;

  // Trace names: the query is "view1", the map "view2" (DUSt3R's names), plus "map.rays_embed".
  FastForwardPrediction forward(const Dust3rEncoding& query, const MapTokens& map, TensorTrace* trace = nullptr,
                                FastForwardOutputs outputs = FastForwardOutputs::kQueryAndMap) const;

 private:
  void registerNewParameters(ParameterTable& table);

  FastForwardConfig config_;
  Dust3rModel dust3r_;
  RayEncoder ray_embed_;
  PointEncoder point_embed_;
  nn::Linear map_head_;
  MatchingHead match_head_;
};

}  // namespace ffloc
