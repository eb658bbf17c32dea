#include "ffloc/io/convert_weights.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/io/half.h"
#include "ffloc/io/tensor_archive.h"

namespace ffloc {
namespace {

TEST(ConvertWeights, CheckpointBecomesTheHubSafetensors) {
  FFLOC_REQUIRE_SHARED(pth, "fixtures/dust3r/tiny_model.pth");
  FFLOC_REQUIRE_SHARED(reference_path, "fixtures/dust3r/tiny_model.safetensors");
  const auto dir = testing::makeTempDir("ffloc-convert");
  const auto output = dir / "tiny.safetensors";
  ConvertWeightsOptions options;
  options.quiet = true;
  const ConvertWeightsSummary summary = convertWeights(pth, output, options);
  EXPECT_EQ(summary.tensors_read, 661u);
  EXPECT_EQ(summary.tensors_written, 653u);
  EXPECT_EQ(summary.aliases_dropped, 8u);

  const auto converted = openSafetensors(output);
  const auto reference = openSafetensors(reference_path);
  EXPECT_EQ(converted->names(), reference->names());
  for (const std::string& name : reference->names()) {
    const TensorView& expected = reference->at(name);
    const TensorView& actual = converted->at(name);
    EXPECT_EQ(actual.dtype, expected.dtype) << name;
    EXPECT_EQ(actual.shape, expected.shape) << name;
    ASSERT_EQ(actual.nbytes, expected.nbytes) << name;
    EXPECT_EQ(std::memcmp(actual.data, expected.data, actual.nbytes), 0) << name;
  }
  EXPECT_EQ(converted->metadata().at("format"), "pt");
  EXPECT_EQ(converted->metadata().at("source"), "tiny_model.pth");
  uint64_t reference_bytes = 0;
  for (const std::string& name : reference->names()) reference_bytes += reference->at(name).nbytes;
  EXPECT_EQ(summary.bytes_written, reference_bytes);
  std::filesystem::remove_all(dir);
}

// A folder as the output failed at the final rename, after the whole conversion; a tensor name
// that is not UTF-8 (a .pth's) was blamed on the output ("cannot encode the header").
TEST(ConvertWeights, AFolderOutputAndANameNoHeaderCanHoldAreRefusedNamingTheirCause) {
  const auto dir = testing::makeTempDir("ffloc-convert-refusals");
  const float values[2] = {1.f, 2.f};
  TensorView view;
  view.name = "w";
  view.dtype = DType::kF32;
  view.shape = {2};
  view.data = reinterpret_cast<const uint8_t*>(values);
  view.nbytes = sizeof(values);
  writeSafetensors(dir / "in.safetensors", {view}, {});
  try {
    convertWeights(dir / "in.safetensors", dir, ConvertWeightsOptions{});
    ADD_FAILURE() << "converted into a folder";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("output: is a folder"), std::string::npos) << e.what();
  }
  view.name = "w\xff";
  try {
    writeSafetensors(dir / "out.safetensors", {view}, {});
    ADD_FAILURE() << "wrote a name that is not UTF-8";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("tensor name 'w\xff' is not UTF-8"), std::string::npos) << e.what();
  }
}

TEST(ConvertWeights, CastsFloatTensorsOnly) {
  FFLOC_REQUIRE_SHARED(fixture, "fixtures/dust3r/case_encoder_single.safetensors");
  const auto dir = testing::makeTempDir("ffloc-convert-cast");
  const auto source = openSafetensors(fixture);
  for (const char* dtype_name : {"f16", "BF16"}) {
    const auto output = dir / (std::string(dtype_name) + ".safetensors");
    ConvertWeightsOptions options;
    options.quiet = true;
    options.float_dtype = parseFloatDType(dtype_name, "--dtype");
    convertWeights(fixture, output, options);
    const auto converted = openSafetensors(output);
    EXPECT_EQ(converted->metadata().at("case"), source->metadata().at("case"));
    for (const std::string& name : source->names()) {
      const TensorView& original = source->at(name);
      const TensorView& cast = converted->at(name);
      if (!isFloatingPoint(original.dtype)) {
        ASSERT_EQ(cast.dtype, original.dtype) << name;
        EXPECT_EQ(std::memcmp(cast.data, original.data, cast.nbytes), 0) << name;
        continue;
      }
      EXPECT_EQ(cast.dtype, *options.float_dtype);
      const std::vector<float> expected = toFloat32(original);
      const std::vector<float> actual = toFloat32(cast);
      ASSERT_EQ(actual.size(), expected.size());
      const float relative = cast.dtype == DType::kF16 ? 1.0f / 2048 : 1.0f / 256;
      for (size_t i = 0; i < actual.size(); ++i) {
        ASSERT_LE(std::fabs(actual[i] - expected[i]), relative * std::fabs(expected[i]) + 1e-7f)
            << name << "[" << i << "]";
      }
    }
  }
  EXPECT_THROW(parseFloatDType("i8", "--dtype"), InputError);
  // Over its own input, however spelt: the f32 original became its f16 copy (second probe).
  const auto original = dir / "f32.safetensors";
  std::filesystem::copy_file(fixture, original);
  const auto size = std::filesystem::file_size(original);
  ConvertWeightsOptions options;
  options.quiet = true;
  options.float_dtype = DType::kF16;
  EXPECT_THROW(convertWeights(original, dir / "." / "f32.safetensors", options), InputError);
  EXPECT_EQ(std::filesystem::file_size(original), size);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace ffloc
