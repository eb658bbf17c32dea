// Strecha: two gt_dense_cameras/*.camera files from the input's pieces, their images written
// by the target.
#include "../support/fuzz_support.h"
#include "ffloc/data/dataset.h"

using namespace ffloc;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto& dir = fuzz::writeDatasetTree(
      data, size, {"gt_dense_cameras/0000.png.camera", "gt_dense_cameras/0001.png.camera"},
      {"images/0000.png", "images/0001.png"});
  fuzz::expectOnlyInputErrors([&] { loadDataset(dir, "strecha"); });
  return 0;
}
