#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <string>

#include "ffloc/model/dust3r_model.h"
#include "ffloc/model/layers.h"

namespace ffloc {

// The query head of the matching family: each query patch's 3D point is a soft assignment over
// the map tokens that carry a point, plus a predicted offset (a 16 px patch at 2.5 m spans about
// 23 cm, so the nearest map token's point alone is coarse), with a confidence.
//
// Logits of query patch i against map token j:
//   s_ij = exp(similarity_scale) <d_i, d_j> + <query_key(x_i), map_key(y_j)> / sqrt(key_dim)
// where d are the encoder's tokens (unit-norm dense RootSIFT: <d_i, d_j> is their Hellinger
// similarity) and x, y the decoder's outputs. A learned no-match logit n_i = no_match(x_i) joins
// them for the matching loss. The point is X_i = sum_j softmax_j(s_ij) P_j + offset(x_i), over
// tokens with a point only, and the confidence 1 + exp(confidence(x_i) + confidence_gain *
// log p_i(best token)), with p over tokens and no-match.
//
// initializeAsNearestNeighbour() zeroes map_key, offset and the confidence and no-match weights:
// the learned terms vanish, so the untrained head is nearest-neighbour descriptor matching
// softened by the temperature (exactly the nearest neighbour as the temperature goes to 0), and
// whatever the decoder computes does not change its output at step 0.
struct MatchingHeadConfig {
  int64_t key_dim = 64;
  // Of the descriptor similarity (in [0, 1]). Near-hard assignment places more queries than a
  // soft one, whose points are averages of candidates: at 0.02, 0.01, 0.005, 0.0025 and 0.001
  // the untrained sift-small model put 16.3, 25.9, 25.9, 27.4 and 25.2 % of the synthetic tuning
  // scenes' queries (seed 5000) within (25 cm, 5 deg) (models/MODEL_CARD.md).
  double initial_temperature = 0.005;
  double initial_no_match_similarity = 0.85;  // the similarity the no-match class starts at
  double initial_confidence_logit = 1.0;

  void validate(const std::string& origin = "matching head") const;
};

struct MatchingPrediction {
  Dust3rPointMap query;  // (B, rows, cols, 3) / (B, rows, cols) at the patch centres
  at::Tensor logits;     // (B, rows * cols, N + 1) float32, the last column no-match; masked
                         // tokens (no point) at a large negative value
};

struct MatchingHead {
  MatchingHeadConfig config;
  nn::Linear query_key, map_key, offset, confidence, no_match;
  at::Tensor similarity_scale;  // (1,) log of the descriptor similarity's inverse temperature
  at::Tensor confidence_gain;   // (1,)

  MatchingHead() = default;
  MatchingHead(const MatchingHeadConfig& config, int64_t decoder_dim);
  void registerIn(ParameterTable& table, const std::string& prefix);
  void initializeAsNearestNeighbour();
  // False when every weight that reads the decoder's outputs is zero (the learned similarity's
  // keys on either side, the offset's, the confidence's and the no-match weights), as at step 0: forward()
  // then gives the same result, bit for bit, for any decoder outputs, so a caller may skip the
  // decoder and pass zeros.
  bool readsDecoderOutput() const;
  // query_descriptors (B, rows * cols, Dd), map_descriptors (B, N, Dd), query_decoded (B, rows *
  // cols, D), map_decoded (B, N, D), map_points (B, N, 3) float32 normalised, map_point_valid
  // (B, N) bool. InputError when no map token carries a point: this head cannot place a query
  // without them.
  MatchingPrediction forward(const at::Tensor& query_descriptors, const at::Tensor& map_descriptors,
                             const at::Tensor& query_decoded, const at::Tensor& map_decoded,
                             const at::Tensor& map_points, const at::Tensor& map_point_valid, int64_t rows,
                             int64_t cols) const;
};

}  // namespace ffloc
