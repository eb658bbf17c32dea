#include <gtest/gtest.h>

#include <ATen/TensorOperators.h>
#include <ATen/ops/abs.h>
#include <ATen/ops/arange.h>
#include <ATen/ops/argmax.h>
#include <ATen/ops/full.h>
#include <ATen/ops/randn.h>
#include <ATen/ops/randperm.h>
#include <ATen/ops/zeros.h>

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "ffloc/core/error.h"
#include "ffloc/core/random.h"
#include "ffloc/model/dense_sift_encoder.h"
#include "ffloc/model/fastforward_model.h"
#include "ffloc/model/image_tensor.h"
#include "ffloc/model/model_loader.h"
#include "ffloc/model/point_encoding.h"

namespace ffloc {
namespace {

// Unit-norm random descriptors, nearly orthogonal to each other.
at::Tensor randomDescriptors(int64_t count, int64_t dim, uint64_t seed) {
  at::Tensor out = at::empty({1, count, dim}, at::kFloat);
  Rng rng(seed);
  float* data = out.data_ptr<float>();
  for (int64_t i = 0; i < count * dim; ++i) data[i] = static_cast<float>(rng.uniform(-1.0, 1.0));
  return out / out.norm(2, -1, true);
}

MapTokens handMadeMap(const at::Tensor& descriptors, const at::Tensor& points, const at::Tensor& valid) {
  const int64_t n = descriptors.size(1);
  MapTokens map;
  map.features = descriptors;
  map.positions = at::zeros({1, n, 2}, at::kLong);
  map.positions.select(2, 1).copy_(at::arange(n, at::kLong).unsqueeze(0));
  at::Tensor rays = at::zeros({1, n, 6}, at::kFloat);
  rays.select(2, 5).fill_(1.0);
  map.rays = rays;
  map.image_index = at::zeros({1, n}, at::kLong);
  map.token_index = at::arange(n, at::kLong).unsqueeze(0);
  map.points = points;
  map.point_valid = valid;
  return map;
}

class UntrainedMatchingModel : public ::testing::Test {
 protected:
  void SetUp() override { loaded_ = loadModel("random:sift-tiny:3"); }
  FastForwardModel& model() { return *loaded_.model; }
  Dust3rEncoding queryOfTokens(const at::Tensor& tokens, int64_t rows, int64_t cols) {
    Dust3rEncoding query;
    query.tokens = tokens;
    query.positions = patchPositions(1, rows, cols, at::kCPU);
    query.height = rows * model().config().dust3r.patch_size;
    query.width = cols * model().config().dust3r.patch_size;
    return query;
  }
  at::Tensor& parameter(const std::string& name) {
    const ParameterTable table = model().parameterTable();
    for (const ParameterTable::Entry& entry : table.entries()) {
      if (entry.name == name) return *entry.tensor;
    }
    throw std::runtime_error("no parameter " + name);
  }
  LoadedModel loaded_;
};

// The untrained matching model is nearest-neighbour descriptor matching: every query patch takes
// the point of the map token whose descriptor is most similar, whatever the random decoder does.
TEST_F(UntrainedMatchingModel, StepZeroIsNearestNeighbourMatching) {
  const int64_t dim = model().config().dust3r.enc_dim, rows = 2, cols = 3, map_tokens = 40;
  const at::Tensor map_descriptors = randomDescriptors(map_tokens, dim, 11);
  at::Tensor points = at::randn({1, map_tokens, 3}, at::kFloat);
  at::Tensor valid = at::ones({1, map_tokens}, at::kBool);
  valid[0][7] = false;  // a token without a point is never chosen, even as the best descriptor
  // Query patch i looks like map token nearest[i], with some noise.
  const std::vector<int64_t> nearest = {5, 17, 7, 30, 2, 39};
  at::Tensor query_tokens = at::empty({1, rows * cols, dim}, at::kFloat);
  const at::Tensor noise = randomDescriptors(rows * cols, dim, 12);
  for (int64_t i = 0; i < rows * cols; ++i) query_tokens[0][i] = map_descriptors[0][nearest[i]] * 0.9 + noise[0][i] * 0.1;
  // Patch 2's best descriptor (token 7) has no point; its best token with a point is 20.
  query_tokens[0][2] = map_descriptors[0][7] * 0.6 + map_descriptors[0][20] * 0.4;
  query_tokens = query_tokens / query_tokens.norm(2, -1, true);
  const FastForwardPrediction prediction =
      model().forward(queryOfTokens(query_tokens, rows, cols), handMadeMap(map_descriptors, points, valid));
  ASSERT_EQ(prediction.query.pts3d.sizes(), at::IntArrayRef({1, rows, cols, 3}));
  ASSERT_EQ(prediction.match_logits.sizes(), at::IntArrayRef({1, rows * cols, map_tokens + 1}));
  for (int64_t i = 0; i < rows * cols; ++i) {
    // The brute-force nearest neighbour among tokens with a point.
    at::Tensor similarity = (map_descriptors[0] * query_tokens[0][i]).sum(-1);
    similarity[7] = -1;
    const int64_t expected = at::argmax(similarity).item<int64_t>();
    EXPECT_EQ(expected, i == 2 ? 20 : nearest[i]);
    EXPECT_EQ(at::argmax(prediction.match_logits[0][i].narrow(0, 0, map_tokens)).item<int64_t>(), expected) << i;
    const at::Tensor predicted = prediction.query.pts3d[0][i / cols][i % cols];
    EXPECT_LT(at::abs(predicted - points[0][expected]).max().item<double>(), 1e-3) << "patch " << i;
    EXPECT_GE(prediction.query.conf[0][i / cols][i % cols].item<double>(), 1.0);
  }
}

// At step 0 the head reads nothing the decoder computes, so localisation (the query's points
// alone) skips the decoder and gets the same points bit for bit; once a weight that reads the
// decoder is non-zero, the decoder runs again.
TEST_F(UntrainedMatchingModel, QueryAloneSkipsADecoderTheHeadDoesNotRead) {
  const int64_t dim = model().config().dust3r.enc_dim, rows = 3, cols = 4, map_tokens = 30;
  const MapTokens map = handMadeMap(randomDescriptors(map_tokens, dim, 21), at::randn({1, map_tokens, 3}, at::kFloat),
                                    at::ones({1, map_tokens}, at::kBool));
  const Dust3rEncoding query = queryOfTokens(randomDescriptors(rows * cols, dim, 22), rows, cols);
  c10::InferenceMode inference;
  const auto queryPointsEqual = [&](const char* when) {
    const FastForwardPrediction full = model().forward(query, map);
    const FastForwardPrediction alone = model().forward(query, map, nullptr, FastForwardOutputs::kQuery);
    EXPECT_TRUE(at::equal(full.query.pts3d, alone.query.pts3d)) << when;
    EXPECT_TRUE(at::equal(full.query.conf, alone.query.conf)) << when;
    EXPECT_TRUE(full.map.pts3d.defined()) << when;
    EXPECT_FALSE(alone.map.pts3d.defined()) << when;
    return full;
  };
  ASSERT_EQ(model().config().query_head, QueryHeadKind::kMatching);
  queryPointsEqual("step 0");
  // Proof that the decoder did not run: a decoder that outputs NaN poisons the full forward, not
  // the query alone.
  at::Tensor& decoder_bias = parameter("dec_norm.bias");
  const at::Tensor kept_bias = decoder_bias.clone();
  decoder_bias.fill_(std::numeric_limits<float>::quiet_NaN());
  EXPECT_FALSE(at::isfinite(model().forward(query, map).query.pts3d).all().item<bool>());
  EXPECT_TRUE(at::isfinite(model().forward(query, map, nullptr, FastForwardOutputs::kQuery).query.pts3d)
                  .all()
                  .item<bool>());
  decoder_bias.copy_(kept_bias);

  // A trained offset makes the points depend on the decoder: a different decoder (here its last
  // norm's bias moved) must then move them, in both calls alike.
  parameter("match_head.offset.weight").normal_(0, 0.1);
  const FastForwardPrediction trained = queryPointsEqual("trained offset");
  decoder_bias.add_(0.5);
  const FastForwardPrediction moved = queryPointsEqual("trained offset, another decoder");
  EXPECT_FALSE(at::allclose(trained.query.pts3d, moved.query.pts3d));
}

TEST_F(UntrainedMatchingModel, RefusesAMapWithoutPoints) {
  const int64_t dim = model().config().dust3r.enc_dim;
  const at::Tensor descriptors = randomDescriptors(8, dim, 1);
  Dust3rEncoding query;
  query.tokens = descriptors.narrow(1, 0, 2);
  query.positions = patchPositions(1, 1, 2, at::kCPU);
  query.height = 16;
  query.width = 32;
  MapTokens without = handMadeMap(descriptors, at::zeros({1, 8, 3}), at::zeros({1, 8}, at::kBool));
  EXPECT_THROW(model().forward(query, without), InputError);
  without.points = at::Tensor();
  without.point_valid = at::Tensor();
  EXPECT_THROW(model().forward(query, without), InputError);
}

TEST(PointEncoder, TokensWithoutAPointKeepOnlyTheirRay) {
  PointEncoderConfig config;
  config.frequencies = 3;
  PointEncoder encoder(config, 8);
  Rng rng(5);
  for (nn::Linear* layer : {&encoder.fc1, &encoder.fc2}) {
    layer->weight = at::empty({layer->out, layer->in}, at::kFloat);
    float* w = layer->weight.data_ptr<float>();
    for (int64_t i = 0; i < layer->weight.numel(); ++i) w[i] = static_cast<float>(rng.uniform(-0.5, 0.5));
    layer->bias = at::full({layer->out}, 0.1, at::kFloat);
  }
  at::Tensor points = at::randn({1, 4, 3});
  points[0][2][0] = std::numeric_limits<float>::quiet_NaN();  // damaged or missing: masked, no NaN out
  at::Tensor valid = at::ones({1, 4}, at::kBool);
  valid[0][1] = false;
  valid[0][2] = false;
  const at::Tensor out = encoder.forward(points, valid);
  ASSERT_EQ(out.sizes(), at::IntArrayRef({1, 4, 8}));
  EXPECT_TRUE(out.isfinite().all().item<bool>());
  EXPECT_EQ(out[0][1].abs().max().item<double>(), 0.0);
  EXPECT_EQ(out[0][2].abs().max().item<double>(), 0.0);
  EXPECT_GT(out[0][0].abs().max().item<double>(), 0.0);
  EXPECT_GT(out[0][3].abs().max().item<double>(), 0.0);
}

TEST(PointEncoder, ContractionKeepsTheUnitBallAndFoldsTheRest) {
  const at::Tensor inside = at::full({1, 3}, 0.5);
  EXPECT_LT(at::abs(contractPoints(inside) - inside * 0.5).max().item<double>(), 1e-7);
  at::Tensor far = at::zeros({1, 3});
  far[0][0] = 1000.0;
  EXPECT_NEAR(contractPoints(far)[0][0].item<double>(), 0.5 * (2.0 - 1e-3), 1e-6);
  EXPECT_LE(contractPoints(at::randn({100, 3}) * 50).abs().max().item<double>(), 1.0);
}

TEST(MapTokenGathering, PointsFollowTheirTokensAndNaNMeansNone) {
  std::vector<Dust3rEncoding> images(2);
  std::vector<at::Tensor> rays, points;
  for (int k = 0; k < 2; ++k) {
    images[k].tokens = at::full({1, 3, 4}, static_cast<double>(k));
    images[k].positions = patchPositions(1, 1, 3, at::kCPU);
    rays.push_back(at::zeros({1, 3, 6}));
    at::Tensor p = at::arange(9, at::kFloat).reshape({1, 3, 3}) + 100.0 * k;
    points.push_back(p);
  }
  points[1][0][2][1] = std::numeric_limits<float>::quiet_NaN();
  at::Tensor indices = at::zeros({3, 2}, at::kLong);
  indices[0][0] = 1, indices[0][1] = 2;  // the NaN one
  indices[1][0] = 0, indices[1][1] = 1;
  indices[2][0] = 1, indices[2][1] = 0;
  const MapTokens map = gatherMapTokens(images, rays, indices, points);
  EXPECT_FALSE(map.point_valid[0][0].item<bool>());
  EXPECT_TRUE(map.point_valid[0][1].item<bool>());
  EXPECT_EQ(map.points[0][1][0].item<float>(), 3.0f);
  EXPECT_EQ(map.points[0][2][2].item<float>(), 102.0f);
  EXPECT_TRUE(map.points.isfinite().all().item<bool>());
  EXPECT_FALSE(gatherMapTokens(images, rays, indices).points.defined());
}

// A textured image and the same image shifted by one patch: interior patches give the same
// descriptors at the shifted token, and every token is unit length.
TEST(DenseSiftEncoder, DescriptorsFollowTheImageContent) {
  cv::Mat rgb(96, 128, CV_8UC3);
  cv::RNG rng(3);
  rng.fill(rgb, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(rgb, rgb, cv::Size(5, 5), 1.5);
  cv::Mat shifted = cv::Mat::zeros(rgb.size(), rgb.type());
  rgb(cv::Rect(0, 0, 112, 96)).copyTo(shifted(cv::Rect(16, 0, 112, 96)));
  const DenseSiftConfig config;
  const Dust3rEncoding a = denseSiftEncode(normalizedImageTensor(rgb), 16, config);
  const Dust3rEncoding b = denseSiftEncode(normalizedImageTensor(shifted), 16, config);
  ASSERT_EQ(a.tokens.sizes(), at::IntArrayRef({1, 6 * 8, config.tokenDim()}));
  EXPECT_LT(at::abs(a.tokens.norm(2, -1) - 1.0).max().item<double>(), 1e-4);
  // Patch (3, 3) of the original is patch (3, 4) of the shifted image, far from every border.
  const at::Tensor same = (a.tokens[0][3 * 8 + 3] * b.tokens[0][3 * 8 + 4]).sum();
  const at::Tensor other = (a.tokens[0][3 * 8 + 3] * b.tokens[0][3 * 8 + 3]).sum();
  EXPECT_GT(same.item<double>(), 0.99);
  EXPECT_LT(other.item<double>(), same.item<double>() - 0.05);
  EXPECT_THROW(denseSiftEncode(normalizedImageTensor(rgb).narrow(2, 0, 90), 16, config), InputError);
}

TEST(FastForwardConfigJson, RoundTripsEveryPreset) {
  for (const char* name : {"tiny", "sift-tiny", "sift-small"}) {
    const FastForwardConfig config = FastForwardConfig::preset(name);
    const FastForwardConfig back = fastForwardConfigFromJson(toJson(config), "test");
    EXPECT_EQ(toJson(back), toJson(config)) << name;
  }
  nlohmann::json broken = toJson(FastForwardConfig::preset("sift-tiny"));
  broken["encoder"] = "resnet";
  EXPECT_THROW(fastForwardConfigFromJson(broken, "test"), InputError);
  broken = toJson(FastForwardConfig::preset("sift-tiny"));
  broken["enc_dim"] = 100;
  EXPECT_THROW(fastForwardConfigFromJson(broken, "test"), InputError);
  broken.erase("dec_dim");
  EXPECT_THROW(fastForwardConfigFromJson(broken, "test"), InputError);

  // Found by an outside probe: fractions were truncated, 2^70 called "must be positive", an array
  // "missing a field", and an unknown field taken; a damaged architecture loaded as another network.
  const auto errorFor = [](const nlohmann::json& json) {
    try {
      fastForwardConfigFromJson(json, "m.safetensors: metadata 'architecture'");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const nlohmann::json good = toJson(FastForwardConfig::preset("sift-tiny"));
  nlohmann::json changed = good;
  changed["dec_depth"] = 10.9;
  EXPECT_EQ(errorFor(changed), "m.safetensors: metadata 'architecture': field 'dec_depth': expected an integer, got 10.9");
  changed = good;
  changed["enc_dim"] = 1180591620717411303424.0;
  EXPECT_NE(errorFor(changed).find("field 'enc_dim': expected an integer"), std::string::npos) << errorFor(changed);
  changed = good;
  changed["dpt_layer_dims"][1] = 96.5;
  EXPECT_NE(errorFor(changed).find("field 'dpt_layer_dims': expected an integer"), std::string::npos) << errorFor(changed);
  changed = good;
  changed["bogus"] = 1;
  EXPECT_EQ(errorFor(changed), "m.safetensors: metadata 'architecture': field 'bogus': not a field of the architecture");
  EXPECT_EQ(errorFor(nlohmann::json::array({1, 2})),
            "m.safetensors: metadata 'architecture': expected an object of the architecture's fields, got array");
}

}  // namespace
}  // namespace ffloc
