#include "ffloc/model/matching_head.h"

#include <ATen/TensorOperators.h>
#include <ATen/ops/cat.h>
#include <ATen/ops/exp.h>
#include <ATen/ops/full.h>
#include <ATen/ops/log_softmax.h>
#include <ATen/ops/matmul.h>
#include <ATen/ops/softmax.h>
#include <ATen/ops/where.h>
#include <ATen/ops/zeros.h>
#include <ATen/ops/zeros_like.h>

#include <cmath>

#include "ffloc/core/error.h"

namespace ffloc {

namespace {
// Large enough that exp() of it relative to any real logit is 0 in float32, small enough that
// differences of two of them stay finite.
constexpr double kMaskedLogit = -1e4;
}  // namespace

void MatchingHeadConfig::validate(const std::string& origin) const {
  if (key_dim <= 0) throwInputError(origin, 0, "field 'key_dim': must be positive");
  if (!(initial_temperature > 0 && initial_temperature <= 10)) {
    throwInputError(origin, 0, "field 'initial_temperature': must be in (0, 10]");
  }
  if (!std::isfinite(initial_no_match_similarity)) throwInputError(origin, 0, "field 'initial_no_match_similarity': must be finite");
  if (!std::isfinite(initial_confidence_logit)) throwInputError(origin, 0, "field 'initial_confidence_logit': must be finite");
}

MatchingHead::MatchingHead(const MatchingHeadConfig& config, int64_t decoder_dim)
    : config(config),
      query_key(decoder_dim, config.key_dim),
      map_key(decoder_dim, config.key_dim),
      offset(decoder_dim, 3),
      confidence(decoder_dim, 1),
      no_match(decoder_dim, 1) {}

void MatchingHead::registerIn(ParameterTable& table, const std::string& prefix) {
  query_key.registerIn(table, prefix + ".query_key");
  map_key.registerIn(table, prefix + ".map_key");
  offset.registerIn(table, prefix + ".offset");
  confidence.registerIn(table, prefix + ".confidence");
  no_match.registerIn(table, prefix + ".no_match");
  table.add(prefix + ".similarity_scale", {1}, &similarity_scale);
  table.add(prefix + ".confidence_gain", {1}, &confidence_gain);
}

void MatchingHead::initializeAsNearestNeighbour() {
  const at::TensorOptions f32 = at::TensorOptions().dtype(at::kFloat).device(query_key.weight.device());
  const double inverse_temperature = 1.0 / config.initial_temperature;
  map_key.weight = at::zeros({map_key.out, map_key.in}, f32);
  map_key.bias = at::zeros({map_key.out}, f32);
  offset.weight = at::zeros({offset.out, offset.in}, f32);
  offset.bias = at::zeros({offset.out}, f32);
  confidence.weight = at::zeros({1, confidence.in}, f32);
  confidence.bias = at::full({1}, config.initial_confidence_logit, f32);
  no_match.weight = at::zeros({1, no_match.in}, f32);
  no_match.bias = at::full({1}, config.initial_no_match_similarity * inverse_temperature, f32);
  similarity_scale = at::full({1}, std::log(inverse_temperature), f32);
  confidence_gain = at::full({1}, 1.0, f32);
}

bool MatchingHead::readsDecoderOutput() const {
  // The learned similarity vanishes when either side's keys are zero for every input.
  const bool learned_similarity_vanishes = (!map_key.weight.any().item<bool>() && !map_key.bias.any().item<bool>()) ||
                                           (!query_key.weight.any().item<bool>() && !query_key.bias.any().item<bool>());
  return !learned_similarity_vanishes || offset.weight.any().item<bool>() || confidence.weight.any().item<bool>() ||
         no_match.weight.any().item<bool>();
}

MatchingPrediction MatchingHead::forward(const at::Tensor& query_descriptors, const at::Tensor& map_descriptors,
                                         const at::Tensor& query_decoded, const at::Tensor& map_decoded,
                                         const at::Tensor& map_points, const at::Tensor& map_point_valid, int64_t rows,
                                         int64_t cols) const {
  const int64_t batch = query_decoded.size(0), tokens = map_decoded.size(1);
  if (query_decoded.size(1) != rows * cols || query_descriptors.size(1) != rows * cols ||
      map_descriptors.size(1) != tokens || map_points.sizes() != at::IntArrayRef({batch, tokens, 3}) ||
      map_point_valid.sizes() != at::IntArrayRef({batch, tokens})) {
    throwInputError("matching head", 0, "inconsistent query, map and point shapes");
  }
  if (!map_point_valid.any().item<bool>()) {
    throwInputError("map", 0, "no map token carries a 3D point: the matching model needs mapping depth");
  }
  const at::Tensor x = query_decoded.to(at::kFloat), y = map_decoded.to(at::kFloat);
  const at::Tensor similarity =
      at::matmul(query_descriptors.to(at::kFloat), map_descriptors.to(at::kFloat).transpose(1, 2));
  const at::Tensor learned = at::matmul(query_key.forward(x), map_key.forward(y).transpose(1, 2)) /
                             std::sqrt(static_cast<double>(config.key_dim));
  const at::Tensor valid = map_point_valid.to(x.device()).unsqueeze(1);  // (B, 1, N)
  const at::Tensor token_logits =
      at::where(valid, at::exp(similarity_scale) * similarity + learned, at::full({}, kMaskedLogit, x.options()));
  const at::Tensor logits = at::cat({token_logits, no_match.forward(x)}, -1);

  const at::Tensor safe_points =
      at::where(valid.transpose(1, 2), map_points.to(x.device(), at::kFloat), at::zeros_like(map_points, x.options()));
  const at::Tensor points = at::matmul(at::softmax(token_logits, -1), safe_points) + offset.forward(x);
  const at::Tensor best_log_probability = std::get<0>(at::log_softmax(logits, -1).narrow(-1, 0, tokens).max(-1, true));
  const at::Tensor confidence_logit = confidence.forward(x) + confidence_gain * best_log_probability;

  MatchingPrediction out;
  out.query.pts3d = points.reshape({batch, rows, cols, 3});
  out.query.conf = (1.0 + at::exp(confidence_logit)).reshape({batch, rows, cols});
  out.logits = logits;
  return out;
}

}  // namespace ffloc
