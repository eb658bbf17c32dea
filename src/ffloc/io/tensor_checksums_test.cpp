#include "ffloc/io/tensor_checksums.h"

#include <gtest/gtest.h>

#include <cstring>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/data/scene_test_util.h"
#include "ffloc/io/convert_weights.h"
#include "ffloc/io/testing/safetensors_edit.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;
using testing::expectInputError;

TensorView floatView(const std::string& name, const std::vector<float>& values) {
  TensorView view;
  view.name = name;
  view.dtype = DType::kF32;
  view.shape = {static_cast<int64_t>(values.size())};
  view.data = reinterpret_cast<const uint8_t*>(values.data());
  view.nbytes = values.size() * sizeof(float);
  return view;
}

class ChecksummedFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::makeTempDir("ffloc-tensor-checksums");
    for (int i = 0; i < 40; ++i) {
      values_.emplace_back(i * 7 + 1);
      for (size_t k = 0; k < values_.back().size(); ++k) values_.back()[k] = 0.25f * static_cast<float>(k) - i;
    }
    for (size_t i = 0; i < values_.size(); ++i) views_.push_back(floatView("t" + std::to_string(i), values_[i]));
    file_ = dir_ / "state.safetensors";
    writeSafetensors(file_, views_, withChecksums(views_, {{"format", "test"}, {"step", "12"}}));
  }

  fs::path dir_, file_;
  std::vector<std::vector<float>> values_;
  std::vector<TensorView> views_;
};

TEST_F(ChecksummedFile, AnIntactFilePassesOnAnyNumberOfThreads) {
  const auto archive = openSafetensors(file_);
  EXPECT_EQ(archive->metadata().count(kChecksumsMetadataKey), 1u);
  for (int workers : {1, 3}) EXPECT_NO_THROW(verifyChecksums(*archive, workers));
  for (const TensorView& view : views_) EXPECT_EQ(tensorChecksum(archive->at(view.name)), tensorChecksum(view));
}

TEST_F(ChecksummedFile, AFlippedByteIsNamedByItsTensorTheFirstInFileOrder) {
  testing::flipTensorByte(file_, "t30", 5);
  testing::flipTensorByte(file_, "t17", 2);
  for (int workers : {1, 4}) {
    expectInputError([&] { verifyChecksums(*openSafetensors(file_), workers); },
                     {file_.string() + ": tensor 't17': checksum mismatch (the file is corrupted)"});
  }
  // The metadata alone still match theirs: the step and the settings stay readable.
  EXPECT_NO_THROW(verifyMetadataChecksum(*openSafetensors(file_)));
}

// A file cut short and padded back to its length keeps a valid header.
TEST_F(ChecksummedFile, ATruncatedAndPaddedFileIsRefused) {
  testing::SafetensorsBytes parts = testing::readSafetensorsBytes(file_);
  std::fill(parts.bytes.end() - 100, parts.bytes.end(), '\0');
  testing::writeBytes(file_, parts.bytes);
  expectInputError([&] { verifyChecksums(*openSafetensors(file_), 2); }, {file_.string(), "checksum mismatch"});
}

TEST_F(ChecksummedFile, EditedMetadataAndMissingOrUnlistedTensorsAreRefused) {
  const fs::path copy = dir_ / "copy.safetensors";
  fs::copy_file(file_, copy);
  testing::editMetadata(copy, [](nlohmann::json& metadata) { metadata["step"] = "13"; });
  expectInputError([&] { verifyMetadataChecksum(*openSafetensors(copy)); },
                   {copy.string() + ": metadata checksum mismatch (the file is corrupted)"});

  const std::vector<TensorView> fewer(views_.begin(), views_.end() - 1);
  writeSafetensors(copy, views_, withChecksums(fewer, {}));
  expectInputError([&] { verifyChecksums(*openSafetensors(copy), 1); },
                   {copy.string() + ": tensor 't39': no checksum recorded"});
  writeSafetensors(copy, fewer, withChecksums(views_, {}));
  expectInputError([&] { verifyChecksums(*openSafetensors(copy), 1); },
                   {copy.string() + ": tensor 't39': checksum recorded, but the file has no such tensor"});

  testing::editMetadata(copy, [](nlohmann::json& metadata) { metadata[kChecksumsMetadataKey] = "{\"metadata\": 1"; });
  expectInputError([&] { verifyChecksums(*openSafetensors(copy), 1); },
                   {copy.string() + ": metadata 'ffloc_checksums': invalid JSON"});
}

TEST_F(ChecksummedFile, FilesWithoutChecksumsAreReadUnchecked) {
  testing::editMetadata(file_, [](nlohmann::json& metadata) { metadata.erase(kChecksumsMetadataKey); });
  testing::flipTensorByte(file_, "t3");
  EXPECT_NO_THROW(verifyChecksums(*openSafetensors(file_), 2));
  EXPECT_NO_THROW(verifyMetadataChecksum(*openSafetensors(file_)));
}

// Converted unchecked, a damaged file came out without checksums, as good as any; and the
// input's checksums, copied, did not match the cast tensors.
TEST_F(ChecksummedFile, ConversionVerifiesItsInputAndChecksumsItsOutput) {
  const fs::path output = dir_ / "f16.safetensors";
  ConvertWeightsOptions options;
  options.quiet = true;
  options.float_dtype = DType::kF16;
  convertWeights(file_, output, options);
  const auto converted = openSafetensors(output);
  EXPECT_EQ(converted->at("t1").dtype, DType::kF16);
  EXPECT_NO_THROW(verifyChecksums(*converted, 1));

  testing::flipTensorByte(file_, "t1");
  expectInputError([&] { convertWeights(file_, dir_ / "other.safetensors", options); },
                   {file_.string() + ": tensor 't1': checksum mismatch"});
  EXPECT_FALSE(fs::exists(dir_ / "other.safetensors"));
}

}  // namespace
}  // namespace ffloc
