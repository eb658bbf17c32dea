#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "ffloc/model/dense_sift_encoder.h"
#include "ffloc/model/dust3r_config.h"
#include "ffloc/model/matching_head.h"
#include "ffloc/model/point_encoding.h"
#include "ffloc/model/ray_encoding.h"

namespace ffloc {

// Which encoder tokenises images: DUSt3R's ViT (the paper), or frozen dense SIFT
// (dense_sift_encoder.h), which needs no training.
enum class TokenEncoderKind { kVit, kDenseSift };
// What predicts the query's points: DUSt3R's DPT head (the paper, one point per pixel), or the
// matching head (matching_head.h, one point per patch centre).
enum class QueryHeadKind { kDpt, kMatching };

// A FastForward network: DUSt3R's decoder between a tokeniser and a query head. The paper's model
// is {kVit, no point encoder, kDpt}; the matching family (docs/model.md) is {kDenseSift, point
// encoder, kMatching}.
struct FastForwardConfig {
  Dust3rConfig dust3r;  // with kDenseSift: enc_dim is the descriptor width, enc_depth 0
  RayEncoderConfig rays;
  // Long side of the images the model was trained on; mapping and localisation preprocess to it
  // unless told otherwise. DUSt3R's 512; a FastForward checkpoint records its own.
  int64_t input_long_side = 512;
  TokenEncoderKind encoder = TokenEncoderKind::kVit;
  DenseSiftConfig dense_sift;
  PointEncoderConfig points;
  QueryHeadKind query_head = QueryHeadKind::kDpt;
  MatchingHeadConfig matching;

  // Pixels of the preprocessed query per cell of the predicted point map: 1 for the DPT head,
  // the patch size for the matching head (cell (r, c) is the pixel ((c + 0.5) s - 0.5,
  // (r + 0.5) s - 0.5)).
  int64_t queryGridStride() const { return query_head == QueryHeadKind::kMatching ? dust3r.patch_size : 1; }
  // Whether the model reads its map tokens' 3D points (a point encoder or the matching head), so
  // that maps must carry them.
  bool usesTokenPoints() const { return points.enabled() || query_head == QueryHeadKind::kMatching; }
  // InputError naming the field.
  void validate(const std::string& origin = "model config") const;

  // "tiny", "small", "large": the paper's model at DUSt3R's preset sizes (Dust3rConfig::preset);
  // "sift-tiny", "sift-small": the matching family. InputError for other names.
  static FastForwardConfig preset(const std::string& name);
};

// Every field, as stored in a checkpoint's 'architecture' metadata (head counts and the frozen
// encoder's settings are not visible in tensor shapes).
nlohmann::json toJson(const FastForwardConfig& config);
// InputError naming `origin` and the field for a missing or mistyped entry.
FastForwardConfig fastForwardConfigFromJson(const nlohmann::json& json, const std::string& origin);

}  // namespace ffloc
