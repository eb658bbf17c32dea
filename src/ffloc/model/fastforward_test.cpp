#include <gtest/gtest.h>

#include <ATen/TensorOperators.h>
#include <ATen/ops/abs.h>
#include <ATen/ops/equal.h>
#include <ATen/ops/rand.h>
#include <ATen/ops/zeros.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/model/fastforward_model.h"
#include "ffloc/model/image_tensor.h"
#include "ffloc/model/tensor_conversion.h"

namespace ffloc {
namespace {

double relativeError(const at::Tensor& actual, const at::Tensor& reference) {
  const at::Tensor a = actual.to(at::kDouble), r = reference.to(at::kDouble);
  return at::abs(a - r).max().item<double>() / at::abs(r).max().item<double>();
}

TEST(FourierFeatures, NerfLayout) {
  const at::Tensor x = at::zeros({1, 3});
  x[0][0] = 0.25;
  x[0][1] = -1.0;
  const at::Tensor f = fourierFeatures(x, 2, true);
  ASSERT_EQ(f.size(-1), 15);
  // [x, sin(pi x), cos(pi x), sin(2 pi x), cos(2 pi x)], each three wide.
  EXPECT_FLOAT_EQ(f[0][0].item<float>(), 0.25f);
  EXPECT_NEAR(f[0][3].item<float>(), std::sin(M_PI / 4), 1e-6);
  EXPECT_NEAR(f[0][6].item<float>(), std::cos(M_PI / 4), 1e-6);
  EXPECT_NEAR(f[0][9].item<float>(), 1.0, 1e-6);    // sin(pi / 2)
  EXPECT_NEAR(f[0][13].item<float>(), 1.0, 1e-6);   // cos(-2 pi)
  EXPECT_NEAR(f[0][7].item<float>(), -1.0, 1e-6);   // cos(-pi)
  EXPECT_EQ(fourierFeatures(x, 3, false).size(-1), 18);
  EXPECT_EQ(RayEncoderConfig().inputDim(), 3 * 21 + 3 * 9);
}

TEST(MapTokenSampling, UniformDistinctAndReproducible) {
  const std::vector<int64_t> counts = {35, 24, 15};
  const at::Tensor a = sampleMapTokenIndices(counts, 40, 7);
  ASSERT_EQ(a.size(0), 40);
  EXPECT_TRUE(at::equal(a, sampleMapTokenIndices(counts, 40, 7)));
  EXPECT_FALSE(at::equal(a, sampleMapTokenIndices(counts, 40, 8)));
  std::set<std::pair<int64_t, int64_t>> seen;
  std::set<int64_t> images;
  for (int64_t i = 0; i < 40; ++i) {
    const int64_t k = a[i][0].item<int64_t>(), n = a[i][1].item<int64_t>();
    ASSERT_GE(k, 0);
    ASSERT_LT(k, 3);
    ASSERT_GE(n, 0);
    ASSERT_LT(n, counts[k]);
    seen.insert({k, n});
    images.insert(k);
  }
  EXPECT_EQ(seen.size(), 40u);
  EXPECT_EQ(images.size(), 3u);
  // Asking for at least everything gives everything, in order.
  const at::Tensor all = sampleMapTokenIndices(counts, 1000, 7);
  ASSERT_EQ(all.size(0), 74);
  EXPECT_EQ(all[35][0].item<int64_t>(), 1);
  EXPECT_EQ(all[35][1].item<int64_t>(), 0);
}

class FastForwardTiny : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto dir = testing::sharedPath("fixtures/dust3r");
    if (!dir) GTEST_SKIP() << "shared fixtures/dust3r not found";
    FastForwardConfig config;
    config.dust3r = Dust3rConfig::preset("tiny");
    model_ = std::make_unique<FastForwardModel>(config);
    model_->initializeFromDust3r(*openSafetensors(*dir / "tiny_model.safetensors"), 3);
    fixture_ = openSafetensors(*dir / "case_pair_mixed.safetensors");
    query_ = model_->encode(normalizedImageTensor(toTorch(fixture_->at("view1.img_uint8"))));
    mapping_ = model_->encode(normalizedImageTensor(toTorch(fixture_->at("view2.img_uint8"))));
    rays_ = at::rand({1, mapping_.tokens.size(1), 6});
  }

  std::unique_ptr<FastForwardModel> model_;
  std::unique_ptr<TensorArchive> fixture_;
  Dust3rEncoding query_, mapping_;
  at::Tensor rays_;
};

// Freshly initialised from DUSt3R, the ray MLP adds zero, so a map made of all tokens of one
// mapping image in order turns FastForward into DUSt3R on (query, mapping image).
TEST_F(FastForwardTiny, InitialisedModelReproducesDust3rPair) {
  const int64_t tokens = mapping_.tokens.size(1);
  const MapTokens map = gatherMapTokens({mapping_}, {rays_}, sampleMapTokenIndices({tokens}, tokens, 0));
  TensorTrace trace;
  const FastForwardPrediction prediction = model_->forward(query_, map, &trace);
  EXPECT_EQ(at::abs(trace.at("map.rays_embed")).max().item<float>(), 0.0f);
  for (const std::string name : {"view1.dec.block3", "view2.dec.out", "view1.head.raw"}) {
    EXPECT_LE(relativeError(trace.at(name), toTorch(fixture_->at(name))), 1e-5) << name;
  }
  EXPECT_LE(relativeError(prediction.query.pts3d, toTorch(fixture_->at("view1.pts3d"))), 1e-5);
  EXPECT_LE(relativeError(prediction.query.conf, toTorch(fixture_->at("view1.conf"))), 1e-5);
  EXPECT_EQ(prediction.map.pts3d.sizes(), at::IntArrayRef({1, tokens, 3}));
  EXPECT_EQ(prediction.map.conf.sizes(), at::IntArrayRef({1, tokens}));
  EXPECT_GE(prediction.map.conf.min().item<float>(), 1.0f);
}

// Attention does not care about the order of the map tokens as long as each keeps its own
// position: a shuffled map gives the same query prediction and the shuffled map prediction.
TEST_F(FastForwardTiny, MapTokenOrderDoesNotMatter) {
  const int64_t tokens = mapping_.tokens.size(1);
  const at::Tensor ordered = sampleMapTokenIndices({tokens}, tokens, 0);
  const at::Tensor shuffled = sampleMapTokenIndices({tokens}, tokens - 1, 11);
  const at::Tensor first = shuffled.narrow(0, 0, tokens - 1);
  const FastForwardPrediction a = model_->forward(query_, gatherMapTokens({mapping_}, {rays_}, first));
  // The same set in the original token order.
  std::vector<int64_t> order(static_cast<size_t>(tokens - 1));
  for (int64_t i = 0; i < tokens - 1; ++i) order[i] = first[i][1].item<int64_t>();
  std::vector<int64_t> sorted = order;
  std::sort(sorted.begin(), sorted.end());
  at::Tensor sorted_indices = ordered.index_select(0, at::tensor(sorted, at::kLong));
  const FastForwardPrediction b = model_->forward(query_, gatherMapTokens({mapping_}, {rays_}, sorted_indices));
  EXPECT_LE(relativeError(a.query.pts3d, b.query.pts3d), 1e-5);
  for (int64_t i = 0; i < tokens - 1; ++i) {
    const int64_t j = std::lower_bound(sorted.begin(), sorted.end(), order[i]) - sorted.begin();
    EXPECT_LE(at::abs(a.map.pts3d[0][i] - b.map.pts3d[0][j]).max().item<float>(), 1e-4) << i;
  }
}

TEST_F(FastForwardTiny, MapsFromSeveralImagesAndRejectsBadIndices) {
  const std::vector<Dust3rEncoding> images = {query_, mapping_};
  const std::vector<at::Tensor> rays = {at::rand({1, query_.tokens.size(1), 6}), rays_};
  const at::Tensor indices = sampleMapTokenIndices({query_.tokens.size(1), mapping_.tokens.size(1)}, 20, 5);
  const MapTokens map = gatherMapTokens(images, rays, indices);
  ASSERT_EQ(map.features.sizes(), at::IntArrayRef({1, 20, 64}));
  for (int64_t i = 0; i < 20; ++i) {
    const int64_t k = indices[i][0].item<int64_t>(), n = indices[i][1].item<int64_t>();
    EXPECT_TRUE(at::equal(map.features[0][i], images[k].tokens[0][n]));
    EXPECT_TRUE(at::equal(map.positions[0][i], images[k].positions[0][n]));
    EXPECT_TRUE(at::equal(map.rays[0][i], rays[k][0][n]));
    EXPECT_EQ(map.image_index[0][i].item<int64_t>(), k);
  }
  const FastForwardPrediction prediction = model_->forward(query_, map);
  EXPECT_EQ(prediction.query.pts3d.sizes(), at::IntArrayRef({1, 80, 112, 3}));
  EXPECT_TRUE(prediction.query.pts3d.isfinite().all().item<bool>());

  at::Tensor bad = indices.clone();
  bad[3][1] = 24;  // image 1 has 24 tokens
  bad[3][0] = 1;
  EXPECT_THROW(gatherMapTokens(images, rays, bad), InputError);
  EXPECT_THROW(gatherMapTokens(images, {rays_}, indices), InputError);
}

TEST_F(FastForwardTiny, CheckpointRoundTripIsStrict) {
  FastForwardModel& model = *model_;
  const ParameterTable table = model.parameterTable();
  // DUSt3R's 661 keys less the second head's 68, plus the ray MLP and the map head.
  EXPECT_EQ(table.keys().size(), 661u - 68u + 6u);
  std::vector<TensorView> views;
  std::vector<at::Tensor> keep;
  for (const ParameterTable::Entry& entry : table.entries()) {
    keep.push_back(entry.tensor->contiguous());
    TensorView view;
    view.name = entry.name;
    view.dtype = DType::kF32;
    view.shape = entry.shape;
    view.data = static_cast<const uint8_t*>(keep.back().data_ptr());
    view.nbytes = keep.back().nbytes();
    views.push_back(view);
  }
  const auto dir = testing::makeTempDir("ffloc-fastforward");
  writeSafetensors(dir / "ff.safetensors", views);
  FastForwardConfig config;
  config.dust3r = Dust3rConfig::preset("tiny");
  FastForwardModel loaded(config);
  loaded.loadWeights(*openSafetensors(dir / "ff.safetensors"));
  const ParameterTable loaded_table = loaded.parameterTable();
  for (size_t i = 0; i < table.entries().size(); ++i) {
    EXPECT_TRUE(at::equal(*table.entries()[i].tensor, *loaded_table.entries()[i].tensor)) << table.entries()[i].name;
  }
  // A plain DUSt3R checkpoint is not a FastForward checkpoint.
  FastForwardModel strict(config);
  EXPECT_THROW(strict.loadWeights(*openSafetensors(*testing::sharedPath("fixtures/dust3r/tiny_model.safetensors"))),
               InputError);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace ffloc
