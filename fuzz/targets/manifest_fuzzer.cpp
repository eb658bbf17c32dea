// The native manifest, found the way the CLI finds it (format "auto"), with the split files
// applied: manifest.json, split_mapping.txt, split_query.txt from the input's pieces.
#include "../support/fuzz_support.h"
#include "ffloc/data/dataset.h"

using namespace ffloc;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto& dir = fuzz::writeDatasetTree(data, size, {"manifest.json", "split_mapping.txt", "split_query.txt"},
                                           {"images/a.png", "images/b.png"});
  fuzz::expectOnlyInputErrors([&] { loadDataset(dir, "auto"); });
  return 0;
}
