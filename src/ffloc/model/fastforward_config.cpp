#include "ffloc/model/fastforward_config.h"

#include <array>
#include <cstdint>
#include <type_traits>

#include "ffloc/core/error.h"

namespace ffloc {

void FastForwardConfig::validate(const std::string& origin) const {
  dust3r.validate(origin);
  if (input_long_side < dust3r.patch_size || input_long_side > 8192) {
    throwInputError(origin, 0, "field 'input_long_side': must be in [patch size, 8192]");
  }
  if (encoder == TokenEncoderKind::kDenseSift) {
    dense_sift.validate(origin);
    if (dust3r.enc_dim != dense_sift.tokenDim()) {
      throwInputError(origin, 0, "field 'enc_dim': the dense-sift encoder gives " + std::to_string(dense_sift.tokenDim()) +
                                     "-wide tokens, the decoder expects " + std::to_string(dust3r.enc_dim));
    }
    if (dust3r.enc_depth != 0) throwInputError(origin, 0, "field 'enc_depth': must be 0 with the dense-sift encoder");
  }
  if (points.frequencies < 0 || points.frequencies > 16) throwInputError(origin, 0, "field 'point_frequencies': must be in [0, 16]");
  if (query_head == QueryHeadKind::kMatching) matching.validate(origin);
}

FastForwardConfig FastForwardConfig::preset(const std::string& name) {
  FastForwardConfig config;
  if (name == "tiny" || name == "small" || name == "large") {
    config.dust3r = Dust3rConfig::preset(name);
    return config;
  }
  if (name != "sift-tiny" && name != "sift-small") {
    throwInputError("model", 0, "unknown preset '" + name + "' (expected tiny, small, large, sift-tiny or sift-small)");
  }
  config.encoder = TokenEncoderKind::kDenseSift;
  config.query_head = QueryHeadKind::kMatching;
  config.input_long_side = 256;
  config.dust3r.enc_dim = config.dense_sift.tokenDim();
  config.dust3r.enc_depth = 0;
  config.dust3r.enc_heads = 4;
  config.dust3r.dec_depth = 4;
  config.dust3r.dec_heads = 4;
  config.dust3r.dec_dim = name == "sift-tiny" ? 48 : 128;
  config.rays.origin_frequencies = 4;
  config.rays.direction_frequencies = 4;
  config.points.frequencies = 4;
  if (name == "sift-tiny") config.matching.key_dim = 16;
  return config;
}

namespace {

std::string encoderName(TokenEncoderKind kind) { return kind == TokenEncoderKind::kVit ? "vit" : "dense-sift"; }
std::string headName(QueryHeadKind kind) { return kind == QueryHeadKind::kDpt ? "dpt" : "matching"; }

template <typename T>
T field(const nlohmann::json& json, const std::string& key, const std::string& origin) {
  if (!json.contains(key)) throwInputError(origin, 0, "field '" + key + "' is missing");
  const nlohmann::json& value = json.at(key);
  // get<int64_t> truncated 10.9 to 10 and wrapped 2^70, so a damaged architecture loaded as
  // another network without a word (found by an outside probe).
  const auto requireInteger = [&](const nlohmann::json& number) {
    if (!number.is_number_integer() || (number.is_number_unsigned() && number.get<uint64_t>() > INT64_MAX))
      throwInputError(origin, 0, "field '" + key + "': expected an integer, got " + value.dump());
  };
  if constexpr (std::is_same_v<T, int64_t>) requireInteger(value);
  if constexpr (std::is_same_v<T, std::array<int64_t, 4>>)
    if (value.is_array())
      for (const nlohmann::json& entry : value) requireInteger(entry);
  try {
    return value.get<T>();
  } catch (const nlohmann::json::exception&) {
    throwInputError(origin, 0, "field '" + key + "' has the wrong type: " + value.dump());
  }
}

}  // namespace

nlohmann::json toJson(const FastForwardConfig& c) {
  const Dust3rConfig& d = c.dust3r;
  return {{"encoder", encoderName(c.encoder)},
          {"query_head", headName(c.query_head)},
          {"input_long_side", c.input_long_side},
          {"patch_size", d.patch_size},
          {"enc_dim", d.enc_dim},
          {"enc_depth", d.enc_depth},
          {"enc_heads", d.enc_heads},
          {"dec_dim", d.dec_dim},
          {"dec_depth", d.dec_depth},
          {"dec_heads", d.dec_heads},
          {"mlp_ratio", d.mlp_ratio},
          {"rope_base", d.rope_base},
          {"layer_norm_eps", d.layer_norm_eps},
          {"dpt_layer_dims", d.head.layer_dims},
          {"dpt_feature_dim", d.head.feature_dim},
          {"dpt_last_dim", d.head.last_dim},
          {"ray_origin_frequencies", c.rays.origin_frequencies},
          {"ray_direction_frequencies", c.rays.direction_frequencies},
          {"ray_include_input", c.rays.include_input},
          {"ray_hidden_dim", c.rays.hidden_dim},
          {"dense_sift_window_sizes", c.dense_sift.window_sizes},
          {"point_frequencies", c.points.frequencies},
          {"point_hidden_dim", c.points.hidden_dim},
          {"match_key_dim", c.matching.key_dim},
          {"match_initial_temperature", c.matching.initial_temperature},
          {"match_initial_no_match_similarity", c.matching.initial_no_match_similarity},
          {"match_initial_confidence_logit", c.matching.initial_confidence_logit}};
}

FastForwardConfig fastForwardConfigFromJson(const nlohmann::json& json, const std::string& origin) {
  if (!json.is_object()) throwInputError(origin, 0, "expected an object of the architecture's fields, got " + std::string(json.type_name()));
  // A field this version does not know was taken without a word.
  const nlohmann::json known = toJson(FastForwardConfig{});
  for (const auto& [key, value] : json.items())
    if (!known.contains(key)) throwInputError(origin, 0, "field '" + key + "': not a field of the architecture");
  FastForwardConfig c;
  const auto encoder = field<std::string>(json, "encoder", origin);
  if (encoder != "vit" && encoder != "dense-sift") throwInputError(origin, 0, "field 'encoder': expected vit or dense-sift, got '" + encoder + "'");
  c.encoder = encoder == "vit" ? TokenEncoderKind::kVit : TokenEncoderKind::kDenseSift;
  const auto head = field<std::string>(json, "query_head", origin);
  if (head != "dpt" && head != "matching") throwInputError(origin, 0, "field 'query_head': expected dpt or matching, got '" + head + "'");
  c.query_head = head == "dpt" ? QueryHeadKind::kDpt : QueryHeadKind::kMatching;
  c.input_long_side = field<int64_t>(json, "input_long_side", origin);
  Dust3rConfig& d = c.dust3r;
  d.patch_size = field<int64_t>(json, "patch_size", origin);
  d.enc_dim = field<int64_t>(json, "enc_dim", origin);
  d.enc_depth = field<int64_t>(json, "enc_depth", origin);
  d.enc_heads = field<int64_t>(json, "enc_heads", origin);
  d.dec_dim = field<int64_t>(json, "dec_dim", origin);
  d.dec_depth = field<int64_t>(json, "dec_depth", origin);
  d.dec_heads = field<int64_t>(json, "dec_heads", origin);
  d.mlp_ratio = field<int64_t>(json, "mlp_ratio", origin);
  d.rope_base = field<double>(json, "rope_base", origin);
  d.layer_norm_eps = field<double>(json, "layer_norm_eps", origin);
  d.head.layer_dims = field<std::array<int64_t, 4>>(json, "dpt_layer_dims", origin);
  d.head.feature_dim = field<int64_t>(json, "dpt_feature_dim", origin);
  d.head.last_dim = field<int64_t>(json, "dpt_last_dim", origin);
  c.rays.origin_frequencies = field<int64_t>(json, "ray_origin_frequencies", origin);
  c.rays.direction_frequencies = field<int64_t>(json, "ray_direction_frequencies", origin);
  c.rays.include_input = field<bool>(json, "ray_include_input", origin);
  c.rays.hidden_dim = field<int64_t>(json, "ray_hidden_dim", origin);
  c.dense_sift.window_sizes = field<std::vector<double>>(json, "dense_sift_window_sizes", origin);
  c.points.frequencies = field<int64_t>(json, "point_frequencies", origin);
  c.points.hidden_dim = field<int64_t>(json, "point_hidden_dim", origin);
  c.matching.key_dim = field<int64_t>(json, "match_key_dim", origin);
  c.matching.initial_temperature = field<double>(json, "match_initial_temperature", origin);
  c.matching.initial_no_match_similarity = field<double>(json, "match_initial_no_match_similarity", origin);
  c.matching.initial_confidence_logit = field<double>(json, "match_initial_confidence_logit", origin);
  c.validate(origin);
  return c;
}

}  // namespace ffloc
