// NeRF transforms files from the input's pieces: transforms_train.json, transforms_val.json,
// transforms_test.json, then transforms.json (which, when present, is read instead); frames
// train/r_0.png, train/r_1.png and test/r_0.png written by the target.
#include "../support/fuzz_support.h"
#include "ffloc/data/dataset.h"

using namespace ffloc;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto& dir = fuzz::writeDatasetTree(
      data, size, {"transforms_train.json", "transforms_val.json", "transforms_test.json", "transforms.json"},
      {"train/r_0.png", "train/r_1.png", "test/r_0.png"});
  fuzz::expectOnlyInputErrors([&] { loadDataset(dir, "nerf"); });
  return 0;
}
