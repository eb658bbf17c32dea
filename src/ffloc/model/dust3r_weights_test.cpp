// Strict weight loading, configuration inference and the state_dict layout of the official model.

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <ATen/ops/equal.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <fstream>
#include <iterator>
#include <memory>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/model/dust3r_model.h"
#include "ffloc/model/tensor_conversion.h"

namespace ffloc {
namespace {

// An editable in-memory copy of an archive, to build broken checkpoints without writing files.
class MemoryArchive : public TensorArchive {
 public:
  explicit MemoryArchive(const TensorArchive& source) {
    path_ = "memory/" + source.path().filename().string();
    for (const std::string& name : source.names()) {
      const TensorView& view = source.at(name);
      put(name, view.dtype, view.shape, std::vector<uint8_t>(view.data, view.data + view.nbytes));
    }
  }

  void put(const std::string& name, DType dtype, std::vector<int64_t> shape, std::vector<uint8_t> bytes) {
    if (!tensors_.count(name)) names_.push_back(name);
    storage_[name] = std::make_shared<std::vector<uint8_t>>(std::move(bytes));
    TensorView view;
    view.name = name;
    view.dtype = dtype;
    view.shape = std::move(shape);
    view.data = storage_[name]->data();
    view.nbytes = storage_[name]->size();
    tensors_[name] = view;
  }

  void copyAs(const std::string& from, const std::string& to) {
    const TensorView view = at(from);
    put(to, view.dtype, view.shape, std::vector<uint8_t>(view.data, view.data + view.nbytes));
  }

  void remove(const std::string& name) {
    tensors_.erase(name);
    storage_.erase(name);
    names_.erase(std::find(names_.begin(), names_.end(), name));
  }

 private:
  std::map<std::string, std::shared_ptr<std::vector<uint8_t>>> storage_;
};

std::string loadError(const TensorArchive& archive) {
  Dust3rModel model(Dust3rConfig::preset("tiny"));
  try {
    model.loadWeights(archive);
  } catch (const InputError& error) {
    return error.what();
  }
  return "";
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

class Dust3rWeights : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto path = testing::sharedPath("fixtures/dust3r/tiny_model.safetensors");
    if (!path) GTEST_SKIP() << "shared fixtures/dust3r not found";
    stored_ = openSafetensors(*path);
    archive_ = std::make_unique<MemoryArchive>(*stored_);
  }
  std::unique_ptr<TensorArchive> stored_;
  std::unique_ptr<MemoryArchive> archive_;
};

TEST_F(Dust3rWeights, LoadsTinyModelAndFillsAliasesThroughSharing) {
  Dust3rModel model(Dust3rConfig::preset("tiny"));
  model.loadWeights(*stored_);
  const ParameterTable table = model.parameterTable();
  EXPECT_EQ(table.keys().size(), 661u);
  EXPECT_EQ(table.entries().size(), 653u);
  for (const ParameterTable::Entry& entry : table.entries()) {
    ASSERT_TRUE(entry.tensor->defined()) << entry.name;
    EXPECT_TRUE(at::equal(*entry.tensor, toTorch(stored_->at(entry.name)))) << entry.name;
  }
}

// The official checkpoint layout (torch.save of {'model': state_dict, 'args': Namespace}) holds
// both names of each aliased tensor.
TEST_F(Dust3rWeights, LoadsPytorchCheckpointWithBothAliasNames) {
  const auto pth = testing::sharedPath("fixtures/dust3r/tiny_model.pth");
  ASSERT_TRUE(pth);
  const auto checkpoint = openTensorArchive(*pth);
  EXPECT_EQ(checkpoint->names().size(), 661u);
  Dust3rModel model(Dust3rConfig::preset("tiny"));
  model.loadWeights(*checkpoint);
  const ParameterTable table = model.parameterTable();
  for (const ParameterTable::Entry& entry : table.entries()) {
    EXPECT_TRUE(at::equal(*entry.tensor, toTorch(stored_->at(entry.name)))) << entry.name;
  }
}

TEST_F(Dust3rWeights, AcceptsEitherOrBothAliasNames) {
  const std::string rn = "downstream_head2.dpt.scratch.layer3_rn.weight";
  const std::string alias = "downstream_head2.dpt.scratch.layer_rn.2.weight";
  archive_->copyAs(rn, alias);
  EXPECT_EQ(loadError(*archive_), "");
  archive_->remove(rn);
  EXPECT_EQ(loadError(*archive_), "");
  Dust3rModel model(Dust3rConfig::preset("tiny"));
  model.loadWeights(*archive_);
  const ParameterTable table = model.parameterTable();
  const auto found = std::find_if(table.entries().begin(), table.entries().end(),
                                  [&](const ParameterTable::Entry& entry) { return entry.name == rn; });
  ASSERT_NE(found, table.entries().end());
  EXPECT_TRUE(at::equal(*found->tensor, toTorch(stored_->at(rn))));
}

TEST_F(Dust3rWeights, RejectsDifferingAliasCopies) {
  const std::string rn = "downstream_head1.dpt.scratch.layer1_rn.weight";
  const std::string alias = "downstream_head1.dpt.scratch.layer_rn.0.weight";
  archive_->copyAs("downstream_head2.dpt.scratch.layer1_rn.weight", alias);
  const std::string error = loadError(*archive_);
  EXPECT_TRUE(contains(error, alias) && contains(error, rn)) << error;
}

TEST_F(Dust3rWeights, NamesMissingKey) {
  archive_->remove("dec_blocks2.7.cross_attn.projk.bias");
  const std::string error = loadError(*archive_);
  EXPECT_TRUE(contains(error, "tiny_model.safetensors")) << error;
  EXPECT_TRUE(contains(error, "'dec_blocks2.7.cross_attn.projk.bias': missing")) << error;
  EXPECT_TRUE(contains(error, "(48)")) << error;
}

TEST_F(Dust3rWeights, NamesMissingAliasedKeyByBothNames) {
  archive_->remove("downstream_head1.dpt.scratch.layer4_rn.weight");
  const std::string error = loadError(*archive_);
  EXPECT_TRUE(contains(error, "layer4_rn.weight") && contains(error, "layer_rn.3.weight")) << error;
}

TEST_F(Dust3rWeights, NamesUnexpectedKey) {
  archive_->copyAs("enc_norm.bias", "enc_blocks.3.norm1.bias");
  const std::string error = loadError(*archive_);
  EXPECT_TRUE(contains(error, "'enc_blocks.3.norm1.bias': unexpected key")) << error;
}

TEST_F(Dust3rWeights, NamesShapeMismatchWithBothShapes) {
  archive_->put("enc_blocks.1.attn.qkv.weight", DType::kF32, {192, 32}, std::vector<uint8_t>(192 * 32 * 4));
  const std::string error = loadError(*archive_);
  EXPECT_TRUE(contains(error, "'enc_blocks.1.attn.qkv.weight'")) << error;
  EXPECT_TRUE(contains(error, "(192, 32)") && contains(error, "(192, 64)")) << error;
}

TEST_F(Dust3rWeights, RejectsIntegerWeights) {
  archive_->put("decoder_embed.bias", DType::kI64, {48}, std::vector<uint8_t>(48 * 8));
  const std::string error = loadError(*archive_);
  EXPECT_TRUE(contains(error, "'decoder_embed.bias'") && contains(error, "I64")) << error;
}

// All-NaN weights once built a map and localized against it without a word.
TEST_F(Dust3rWeights, NamesNonFiniteWeights) {
  const std::vector<int64_t> shape = archive_->at("decoder_embed.bias").shape;
  std::vector<float> values(static_cast<size_t>(archive_->at("decoder_embed.bias").numel()),
                            std::numeric_limits<float>::quiet_NaN());
  values[1] = std::numeric_limits<float>::infinity();
  std::vector<uint8_t> bytes(values.size() * sizeof(float));
  std::memcpy(bytes.data(), values.data(), bytes.size());
  archive_->put("decoder_embed.bias", DType::kF32, shape, bytes);
  const std::string error = loadError(*archive_);
  EXPECT_TRUE(contains(error, "tiny_model.safetensors")) << error;
  EXPECT_TRUE(contains(error, "'decoder_embed.bias': 48 of its 48 values are not finite")) << error;
}

// 64 little-endian 16-bit values alternating between two bit patterns.
std::vector<uint8_t> alternating16(uint16_t even, uint16_t odd) {
  std::vector<uint8_t> bytes(128);
  for (int i = 0; i < 64; ++i) {
    const uint16_t bits = i % 2 ? odd : even;
    bytes[2 * i] = bits & 0xFF;
    bytes[2 * i + 1] = bits >> 8;
  }
  return bytes;
}

TEST_F(Dust3rWeights, ConvertsHalfAndBfloat16Weights) {
  // 1.5 and -2.25 are exact in both formats: F16 0x3E00 / 0xC080, BF16 0x3FC0 / 0xC010.
  archive_->put("enc_norm.weight", DType::kF16, {64}, alternating16(0x3E00, 0xC080));
  archive_->put("enc_norm.bias", DType::kBF16, {64}, alternating16(0x3FC0, 0xC010));
  Dust3rModel model(Dust3rConfig::preset("tiny"));
  model.loadWeights(*archive_);
  int checked = 0;
  const ParameterTable table = model.parameterTable();
  for (const ParameterTable::Entry& entry : table.entries()) {
    if (entry.name != "enc_norm.weight" && entry.name != "enc_norm.bias") continue;
    EXPECT_EQ(entry.tensor->scalar_type(), at::kFloat);
    EXPECT_EQ((*entry.tensor)[0].item<float>(), 1.5f) << entry.name;
    EXPECT_EQ((*entry.tensor)[63].item<float>(), -2.25f) << entry.name;
    ++checked;
  }
  EXPECT_EQ(checked, 2);
}

TEST_F(Dust3rWeights, InfersTinyConfigFromShapes) {
  Dust3rConfigInference heads;
  heads.enc_head_dim = 16;
  heads.dec_head_dim = 12;
  const Dust3rConfig inferred = inferDust3rConfig(*stored_, heads);
  const Dust3rConfig tiny = Dust3rConfig::preset("tiny");
  EXPECT_EQ(inferred.enc_dim, tiny.enc_dim);
  EXPECT_EQ(inferred.enc_depth, tiny.enc_depth);
  EXPECT_EQ(inferred.enc_heads, tiny.enc_heads);
  EXPECT_EQ(inferred.dec_dim, tiny.dec_dim);
  EXPECT_EQ(inferred.dec_depth, tiny.dec_depth);
  EXPECT_EQ(inferred.dec_heads, tiny.dec_heads);
  EXPECT_EQ(inferred.mlp_ratio, 4);
  EXPECT_EQ(inferred.patch_size, 16);
  EXPECT_EQ(inferred.head.layer_dims, tiny.head.layer_dims);
  EXPECT_EQ(inferred.head.feature_dim, 32);
  EXPECT_EQ(inferred.head.last_dim, 24);
  EXPECT_EQ(inferred.dptHooks(), (std::array<int64_t, 4>{0, 5, 7, 10}));
  // With the official head dim of 64 the tiny widths do not divide.
  EXPECT_THROW(inferDust3rConfig(*stored_), InputError);
}

TEST(Dust3rConfig, RejectsImpossibleSizes) {
  Dust3rConfig config;
  config.enc_heads = 5;
  EXPECT_THROW(config.validate(), InputError);
  config = Dust3rConfig::preset("tiny");
  config.dec_heads = 8;  // head dim 6: RoPE2D needs a multiple of 4
  EXPECT_THROW(config.validate(), InputError);
  EXPECT_THROW(Dust3rConfig::preset("huge"), InputError);
  EXPECT_EQ(Dust3rConfig::preset("large").dptHooks(), (std::array<int64_t, 4>{0, 6, 9, 12}));
}

// Every state_dict key and shape of the official model, in order, from the reference's
// large_config_keys.json; tensors are created on the meta device so nothing is allocated.
TEST(Dust3rLayout, LargeConfigMatchesReferenceStateDict) {
  FFLOC_REQUIRE_SHARED(path, "fixtures/dust3r/large_config_keys.json");
  std::ifstream stream(path);
  std::string text((std::istreambuf_iterator<char>(stream)), std::istreambuf_iterator<char>());
  // Python's json writes the infinite depth bounds as (-)Infinity, which is not JSON.
  for (const std::string token : {"-Infinity", "Infinity"}) {
    for (size_t at = text.find(token); at != std::string::npos; at = text.find(token, at)) {
      text.replace(at, token.size(), "null");
    }
  }
  const nlohmann::json reference = nlohmann::json::parse(text);
  const auto& keys = reference.at("keys");
  ASSERT_EQ(keys.size(), 1009u);

  Dust3rModel model(Dust3rConfig::preset("large"));
  const ParameterTable table = model.parameterTable();
  allocateParameters(table, at::TensorOptions().device(at::kMeta));
  ASSERT_EQ(table.keys().size(), keys.size());
  int64_t unique_parameters = 0;
  for (const ParameterTable::Entry& entry : table.entries()) unique_parameters += entry.tensor->numel();
  EXPECT_EQ(unique_parameters, reference.at("total_parameters_unique").get<int64_t>());
  for (size_t i = 0; i < keys.size(); ++i) {
    const ParameterTable::Key& key = table.keys()[i];
    const ParameterTable::Entry& entry = table.entries()[key.entry];
    ASSERT_EQ(key.name, keys[i].at("name").get<std::string>()) << "key " << i;
    const auto shape = keys[i].at("shape").get<std::vector<int64_t>>();
    EXPECT_EQ(entry.shape, shape) << key.name;
    EXPECT_EQ(entry.tensor->sizes(), at::IntArrayRef(shape)) << key.name;
    EXPECT_EQ(key.is_alias, keys[i].contains("alias_of")) << key.name;
    if (key.is_alias) EXPECT_EQ(entry.name, keys[i].at("alias_of").get<std::string>());
  }
}

}  // namespace
}  // namespace ffloc
