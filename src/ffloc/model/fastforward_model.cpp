#include "ffloc/model/fastforward_model.h"

#include <ATen/TensorOperators.h>
#include <ATen/ops/cat.h>
#include <ATen/ops/empty.h>
#include <ATen/ops/where.h>
#include <ATen/ops/zeros.h>
#include <ATen/ops/zeros_like.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "ffloc/core/error.h"
#include "ffloc/core/random.h"

namespace ffloc {

at::Tensor sampleMapTokenIndices(const std::vector<int64_t>& tokens_per_image, int64_t count, uint64_t seed) {
  std::vector<std::pair<int64_t, int64_t>> all;
  for (size_t k = 0; k < tokens_per_image.size(); ++k) {
    for (int64_t n = 0; n < tokens_per_image[k]; ++n) all.emplace_back(static_cast<int64_t>(k), n);
  }
  if (count < static_cast<int64_t>(all.size())) {
    // Partial Fisher-Yates: the first `count` entries become a uniform sample without replacement.
    Rng rng(seed);
    for (int64_t i = 0; i < count; ++i) std::swap(all[i], all[rng.between(i, static_cast<int64_t>(all.size()) - 1)]);
    all.resize(std::max<int64_t>(count, 0));
  }
  at::Tensor indices = at::empty({static_cast<int64_t>(all.size()), 2}, at::TensorOptions().dtype(at::kLong));
  int64_t* data = indices.data_ptr<int64_t>();
  for (size_t i = 0; i < all.size(); ++i) {
    data[2 * i] = all[i].first;
    data[2 * i + 1] = all[i].second;
  }
  return indices;
}

MapTokens gatherMapTokens(const std::vector<Dust3rEncoding>& images, const std::vector<at::Tensor>& rays,
                          const at::Tensor& indices, const std::vector<at::Tensor>& points) {
  const auto fail = [](const std::string& what) { throwInputError("map tokens", 0, what); };
  if (images.empty() || images.size() != rays.size()) fail("need one ray tensor per mapping image");
  if (!points.empty() && points.size() != images.size()) fail("need one point tensor per mapping image");
  if (indices.dim() != 2 || indices.size(1) != 2 || indices.scalar_type() != at::kLong) {
    fail("indices must be an (M, 2) int64 tensor of (image, token)");
  }
  std::vector<int64_t> offsets;
  std::vector<at::Tensor> features, positions, all_rays, all_points;
  int64_t total = 0;
  for (size_t k = 0; k < images.size(); ++k) {
    const int64_t tokens = images[k].tokens.size(1);
    if (images[k].tokens.size(0) != 1) fail("mapping image " + std::to_string(k) + ": batch must be 1");
    if (rays[k].dim() != 3 || rays[k].size(0) != 1 || rays[k].size(1) != tokens || rays[k].size(2) != 6) {
      fail("mapping image " + std::to_string(k) + ": rays must be (1, " + std::to_string(tokens) + ", 6)");
    }
    if (!points.empty()) {
      if (points[k].dim() != 3 || points[k].size(0) != 1 || points[k].size(1) != tokens || points[k].size(2) != 3) {
        fail("mapping image " + std::to_string(k) + ": points must be (1, " + std::to_string(tokens) + ", 3)");
      }
      all_points.push_back(points[k].to(images[k].tokens.device(), at::kFloat));
    }
    offsets.push_back(total);
    total += tokens;
    features.push_back(images[k].tokens);
    positions.push_back(images[k].positions.to(images[k].tokens.device()));
    all_rays.push_back(rays[k].to(images[k].tokens.device(), at::kFloat));
  }
  const at::Tensor cpu_indices = indices.cpu().contiguous();
  at::Tensor flat = at::empty({indices.size(0)}, at::TensorOptions().dtype(at::kLong));
  const int64_t* pairs = cpu_indices.data_ptr<int64_t>();
  int64_t* flat_data = flat.data_ptr<int64_t>();
  for (int64_t i = 0; i < indices.size(0); ++i) {
    const int64_t image = pairs[2 * i], token = pairs[2 * i + 1];
    if (image < 0 || image >= static_cast<int64_t>(images.size()) || token < 0 ||
        token >= images[image].tokens.size(1)) {
      fail("index " + std::to_string(i) + " = (" + std::to_string(image) + ", " + std::to_string(token) +
           ") is out of range");
    }
    flat_data[i] = offsets[image] + token;
  }
  const at::Tensor select = flat.to(images[0].tokens.device());
  MapTokens map;
  map.features = at::cat(features, 1).index_select(1, select);
  map.positions = at::cat(positions, 1).index_select(1, select);
  map.rays = at::cat(all_rays, 1).index_select(1, select);
  map.image_index = cpu_indices.select(1, 0).unsqueeze(0).clone();
  map.token_index = cpu_indices.select(1, 1).unsqueeze(0).clone();
  if (!points.empty()) {
    const at::Tensor gathered = at::cat(all_points, 1).index_select(1, select);
    map.point_valid = gathered.isfinite().all(-1);
    map.points = at::where(map.point_valid.unsqueeze(-1), gathered, at::zeros_like(gathered));
  }
  return map;
}

FastForwardModel::FastForwardModel(const FastForwardConfig& config)
    : config_(config),
      dust3r_(config.dust3r),
      ray_embed_(config.rays, config.dust3r.enc_dim),
      point_embed_(config.points, config.dust3r.enc_dim),
      map_head_(config.dust3r.dec_dim, config.dust3r.head.num_channels),
      match_head_(config.matching, config.dust3r.dec_dim) {
  config_.validate();
}

void FastForwardModel::registerNewParameters(ParameterTable& table) {
  ray_embed_.registerIn(table, "ray_embed");
  map_head_.registerIn(table, "map_head");
  if (config_.points.enabled()) point_embed_.registerIn(table, "point_embed");
  if (config_.query_head == QueryHeadKind::kMatching) match_head_.registerIn(table, "match_head");
}

ParameterTable FastForwardModel::parameterTable() {
  ParameterTable table =
      dust3r_.parameterTable(config_.query_head == QueryHeadKind::kDpt ? Dust3rHeads::kFirstOnly : Dust3rHeads::kNone,
                             config_.encoder == TokenEncoderKind::kVit);
  registerNewParameters(table);
  return table;
}

Dust3rEncoding FastForwardModel::encode(const at::Tensor& images) const {
  if (config_.encoder == TokenEncoderKind::kVit) return dust3r_.encode(images);
  Dust3rEncoding encoding = denseSiftEncode(images, config_.dust3r.patch_size, config_.dense_sift);
  encoding.tokens = encoding.tokens.to(dust3r_.backboneDtype());
  return encoding;
}

void FastForwardModel::initializeMatchingHeadAsNearestNeighbour() {
  if (config_.query_head != QueryHeadKind::kMatching) throw std::logic_error("the model has no matching head");
  match_head_.initializeAsNearestNeighbour();
  to(dust3r_.device(), dust3r_.backboneDtype());
}

void FastForwardModel::loadWeights(const TensorArchive& archive) {
  loadParameters(parameterTable(), archive);
  to(dust3r_.device(), dust3r_.backboneDtype());
}

namespace {

// Xavier-uniform (PyTorch's default for these layers in DUSt3R) from the project's generator, so
// the initialisation depends neither on the libtorch version's RNG nor on the standard library.
at::Tensor xavierUniform(int64_t out, int64_t in, Rng& rng) {
  at::Tensor weight = at::empty({out, in}, at::TensorOptions().dtype(at::kFloat));
  const double bound = std::sqrt(6.0 / static_cast<double>(in + out));
  float* data = weight.data_ptr<float>();
  for (int64_t i = 0; i < out * in; ++i) data[i] = static_cast<float>(rng.uniform(-bound, bound));
  return weight;
}

}  // namespace

void FastForwardModel::initializeFromDust3r(const TensorArchive& dust3r, uint64_t seed) {
  if (config_.encoder != TokenEncoderKind::kVit || config_.query_head != QueryHeadKind::kDpt || config_.points.enabled()) {
    throwInputError("model", 0, "only the paper's model (ViT encoder, DPT head, no point encoder) starts from DUSt3R");
  }
  ParameterLoadOptions options;
  options.ignored_prefixes = {"downstream_head2."};
  loadParameters(dust3r_.parameterTable(Dust3rHeads::kFirstOnly), dust3r, options);
  Rng rng(seed);
  const at::TensorOptions f32 = at::TensorOptions().dtype(at::kFloat);
  ray_embed_.fc1.weight = xavierUniform(ray_embed_.fc1.out, ray_embed_.fc1.in, rng);
  ray_embed_.fc1.bias = at::zeros({ray_embed_.fc1.out}, f32);
  ray_embed_.fc2.weight = at::zeros({ray_embed_.fc2.out, ray_embed_.fc2.in}, f32);
  ray_embed_.fc2.bias = at::zeros({ray_embed_.fc2.out}, f32);
  map_head_.weight = xavierUniform(map_head_.out, map_head_.in, rng);
  map_head_.bias = at::zeros({map_head_.out}, f32);
  to(dust3r_.device(), dust3r_.backboneDtype());
}

namespace {

void castLinear(nn::Linear& layer, at::Device device, at::ScalarType dtype) {
  for (at::Tensor* tensor : {&layer.weight, &layer.bias}) {
    if (tensor->defined()) *tensor = tensor->to(device, dtype);
  }
}

}  // namespace

void FastForwardModel::to(at::Device device, at::ScalarType backbone_dtype, at::ScalarType head_dtype) {
  dust3r_.to(device, backbone_dtype, head_dtype);
  castLinear(ray_embed_.fc1, device, backbone_dtype);
  castLinear(ray_embed_.fc2, device, backbone_dtype);
  castLinear(point_embed_.fc1, device, backbone_dtype);
  castLinear(point_embed_.fc2, device, backbone_dtype);
  castLinear(map_head_, device, at::kFloat);
  // The matching head decides which map token a patch sees: float32, like the map head.
  for (nn::Linear* layer : {&match_head_.query_key, &match_head_.map_key, &match_head_.offset, &match_head_.confidence,
                            &match_head_.no_match}) {
    castLinear(*layer, device, at::kFloat);
  }
  for (at::Tensor* scalar : {&match_head_.similarity_scale, &match_head_.confidence_gain}) {
    if (scalar->defined()) *scalar = scalar->to(device, at::kFloat);
  }
}

FastForwardPrediction FastForwardModel::forward(const Dust3rEncoding& query, const MapTokens& map, TensorTrace* trace,
                                                FastForwardOutputs outputs) const {
  if (!map.features.defined() || map.features.dim() != 3 || map.features.size(1) == 0) {
    throwInputError("map tokens", 0, "the map is empty");
  }
  at::Tensor points = map.points, point_valid = map.point_valid;
  if (config_.usesTokenPoints() && !points.defined()) {
    points = at::zeros({map.features.size(0), map.features.size(1), 3}, map.features.options().dtype(at::kFloat));
    point_valid = at::zeros({map.features.size(0), map.features.size(1)}, map.features.options().dtype(at::kBool));
  }
  const bool matching = config_.query_head == QueryHeadKind::kMatching;
  const bool skip_decoder =
      matching && outputs == FastForwardOutputs::kQuery && trace == nullptr && !match_head_.readsDecoderOutput();
  std::array<std::vector<at::Tensor>, 2> decoded;
  if (skip_decoder) {
    const at::TensorOptions f32 = query.tokens.options().dtype(at::kFloat);
    const int64_t width = config_.dust3r.dec_dim;
    decoded[0] = {at::zeros({query.tokens.size(0), query.tokens.size(1), width}, f32)};
    decoded[1] = {at::zeros({map.features.size(0), map.features.size(1), width}, f32)};
  } else {
    const at::Tensor ray_features = ray_embed_.forward(map.rays.to(map.features.device()));
    if (trace) (*trace)["map.rays_embed"] = ray_features;
    Dust3rEncoding map_encoding;
    map_encoding.tokens = map.features + ray_features.to(map.features.scalar_type());
    if (config_.points.enabled()) {
      map_encoding.tokens = map_encoding.tokens +
                            point_embed_.forward(points.to(map.features.device()), point_valid.to(map.features.device()))
                                .to(map.features.scalar_type());
    }
    map_encoding.positions = map.positions;
    // The map stream feeds only the map head (and the matching head), which read its last output.
    const DecoderOutputs query_outputs = matching ? DecoderOutputs::kLast : DecoderOutputs::kHeadInputs;
    decoded = dust3r_.decode(query, map_encoding, trace, {query_outputs, DecoderOutputs::kLast});
  }
  FastForwardPrediction out;
  if (matching) {
    const int64_t patch = config_.dust3r.patch_size;
    MatchingPrediction prediction = match_head_.forward(query.tokens, map.features, decoded[0].back(), decoded[1].back(),
                                                        points, point_valid, query.height / patch, query.width / patch);
    out.query = prediction.query;
    out.match_logits = prediction.logits;
  } else {
    out.query = pointMapFromRaw(dust3r_.headForward(0, decoded[0], query.height, query.width, trace, "view1"));
  }
  if (outputs == FastForwardOutputs::kQueryAndMap) {
    out.map = pointsFromRaw(map_head_.forward(decoded[1].back().to(at::kFloat)));
  }
  return out;
}

}  // namespace ffloc
