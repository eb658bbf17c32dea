// 7-Scenes in its original layout: two sequences, their pose files, the split lists and the
// intrinsics file from the input's pieces; the colour images are written by the target.
#include "../support/fuzz_support.h"
#include "ffloc/data/dataset.h"

using namespace ffloc;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto& dir = fuzz::writeDatasetTree(
      data, size,
      {"seq-01/frame-000000.pose.txt", "seq-01/frame-000001.pose.txt", "seq-02/frame-000000.pose.txt",
       "TrainSplit.txt", "TestSplit.txt", "camera-intrinsics.txt", "split_query.txt"},
      {"seq-01/frame-000000.color.png", "seq-01/frame-000001.color.png", "seq-02/frame-000000.color.png"});
  fuzz::expectOnlyInputErrors([&] { loadDataset(dir, "7scenes"); });
  return 0;
}
