// Cambridge Landmarks: dataset_train.txt, dataset_test.txt and reconstruction.nvm from the
// input's pieces, frames seq1/frame00001.png to frame00003.png written by the target.
#include "../support/fuzz_support.h"
#include "ffloc/data/dataset.h"

using namespace ffloc;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto& dir = fuzz::writeDatasetTree(data, size, {"dataset_train.txt", "dataset_test.txt", "reconstruction.nvm"},
                                           {"seq1/frame00001.png", "seq1/frame00002.png", "seq1/frame00003.png"});
  fuzz::expectOnlyInputErrors([&] { loadDataset(dir, "cambridge"); });
  return 0;
}
