#include "ffloc/model/model_loader.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/data/scene_test_util.h"
#include "ffloc/io/tensor_checksums.h"
#include "ffloc/io/testing/safetensors_edit.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;
using testing::expectInputError;

// The head count, which no tensor's shape shows, changed in a saved model's metadata.
void setEncoderHeads(const fs::path& file, int heads) {
  testing::editMetadata(file, [heads](nlohmann::json& metadata) {
    nlohmann::json architecture = nlohmann::json::parse(metadata["architecture"].get<std::string>());
    architecture["enc_heads"] = heads;
    metadata["architecture"] = architecture.dump();
  });
}

void removeChecksums(const fs::path& file) {
  testing::editMetadata(file, [](nlohmann::json& metadata) { metadata.erase(kChecksumsMetadataKey); });
}

// A flipped byte in a saved model loaded as other weights, without a word.
TEST(ModelLoader, RefusesASavedModelWhoseTensorsOrMetadataChanged) {
  const fs::path dir = testing::makeTempDir("ffloc-model-checksums");
  LoadedModel original = loadModel("random:tiny:3");
  const fs::path file = dir / "model.safetensors";
  saveModel(*original.model, file);
  LoadedModel reloaded = loadModel(file.string());
  EXPECT_EQ(parameterFingerprint(*reloaded.model), parameterFingerprint(*original.model));

  const fs::path flipped = dir / "flipped.safetensors";
  fs::copy_file(file, flipped);
  testing::flipTensorByte(flipped, "map_head.weight", 3);
  expectInputError([&] { loadModel(flipped.string()); },
                   {flipped.string() + ": tensor 'map_head.weight': checksum mismatch (the file is corrupted)"});

  const fs::path heads = dir / "heads.safetensors";
  fs::copy_file(file, heads);
  setEncoderHeads(heads, 2);
  expectInputError([&] { loadModel(heads.string()); },
                   {heads.string() + ": metadata checksum mismatch (the file is corrupted)"});
}

// The shipped models, DUSt3R's checkpoints and models saved before checksums have none, and
// load as they did, damage included.
TEST(ModelLoader, FilesWithoutChecksumsLoadAsBefore) {
  EXPECT_EQ(openSafetensors(defaultModelPath())->metadata().count(kChecksumsMetadataKey), 0u);
  EXPECT_EQ(loadModel("default").id.rfind("fastforward/sift-e256x0-d128x4/", 0), 0u);

  const fs::path dir = testing::makeTempDir("ffloc-model-unchecked");
  LoadedModel original = loadModel("random:tiny:3");
  const fs::path file = dir / "model.safetensors";
  saveModel(*original.model, file);
  removeChecksums(file);
  EXPECT_EQ(parameterFingerprint(*loadModel(file.string()).model), parameterFingerprint(*original.model));
  setEncoderHeads(file, 2);
  testing::flipTensorByte(file, "map_head.weight", 3);
  LoadedModel damaged = loadModel(file.string());
  EXPECT_EQ(damaged.model->config().dust3r.enc_heads, 2);
  EXPECT_NE(parameterFingerprint(*damaged.model), parameterFingerprint(*original.model));
}

// FFLOC_MODEL naming nothing was reported as the shipped model missing, "set FFLOC_MODEL".
TEST(ModelLoader, AMissingDefaultModelSaysWhereItWasLookedFor) {
  const char* set = std::getenv("FFLOC_MODEL");
  const std::string before = set != nullptr ? set : "";
  ::setenv("FFLOC_MODEL", "/nonexistent/model.safetensors", 1);
  EXPECT_EQ(modelSpecProblem("default"), "the default model is FFLOC_MODEL's '/nonexistent/model.safetensors', which is not a file");
  ::unsetenv("FFLOC_MODEL");
  EXPECT_EQ(modelSpecProblem("default"), "");  // the shipped one
  if (!before.empty()) ::setenv("FFLOC_MODEL", before.c_str(), 1);
  EXPECT_EQ(modelSpecProblem("random:tiny:x"), "'random:tiny:x': seed must be a whole number in [0, 18446744073709551615]");
  // -1 wrapped to 2^64 - 1, and 2^64 and beyond were clamped to it: two specs, one model.
  EXPECT_EQ(modelSpecProblem("random:tiny:-1"), "'random:tiny:-1': seed must be a whole number in [0, 18446744073709551615]");
  EXPECT_EQ(modelSpecProblem("random:tiny:18446744073709551616"),
            "'random:tiny:18446744073709551616': seed must be a whole number in [0, 18446744073709551615]");
  EXPECT_EQ(modelSpecProblem("random:tiny:18446744073709551615"), "");
  EXPECT_EQ(modelSpecProblem("/nonexistent.pth"), "'/nonexistent.pth': no such file");
  // A training checkpoint's folder given for its model (an outside probe): the file is named.
  const fs::path checkpoint = testing::makeTempDir("ffloc-model-folder");
  EXPECT_EQ(modelSpecProblem(checkpoint.string()), "'" + checkpoint.string() + "': a folder, not a weights file");
  std::ofstream(checkpoint / "model.safetensors") << "x";
  EXPECT_EQ(modelSpecProblem(checkpoint.string()), "'" + checkpoint.string() + "': a folder, not a weights file; its model is '" +
                                                       (checkpoint / "model.safetensors").string() + "'");
  // A run's folder, or its checkpoints folder: the model of the step `latest` names.
  const fs::path run = testing::makeTempDir("ffloc-model-run");
  fs::create_directories(run / "checkpoints" / "step_00000003");
  std::ofstream(run / "checkpoints" / "step_00000003" / "model.safetensors") << "x";
  std::ofstream(run / "checkpoints" / "latest") << "step_00000003\n";
  const std::string latest_model = (run / "checkpoints" / "step_00000003" / "model.safetensors").string();
  for (const fs::path& folder : {run, run / "checkpoints"})
    EXPECT_EQ(modelSpecProblem(folder.string()),
              "'" + folder.string() + "': a folder, not a weights file; its model is '" + latest_model + "'");
}

// The identity maps are checked against covered the parameters only: a checkpoint whose metadata
// changed the preprocessing (dense-SIFT windows, input size) was taken for the model a map was
// built with, and localized nothing (found by an outside probe).
TEST(ModelLoader, TheIdentityCoversTheArchitectureBesideTheParameters) {
  const fs::path dir = testing::makeTempDir("ffloc-model-identity");
  LoadedModel original = loadModel("random:tiny:3");
  const fs::path file = dir / "model.safetensors";
  saveModel(*original.model, file);
  removeChecksums(file);
  const std::string before = loadModel(file.string()).id;
  testing::editMetadata(file, [](nlohmann::json& metadata) {
    nlohmann::json architecture = nlohmann::json::parse(metadata["architecture"].get<std::string>());
    architecture["input_long_side"] = architecture["input_long_side"].get<int>() + 64;
    metadata["architecture"] = architecture.dump();
  });
  const LoadedModel resized = loadModel(file.string());
  EXPECT_EQ(parameterFingerprint(*resized.model), parameterFingerprint(*original.model));
  EXPECT_NE(resized.id, before);
}

}  // namespace
}  // namespace ffloc
