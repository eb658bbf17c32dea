// A COLMAP text model (cameras.txt, images.txt, points3D.txt) and a split file from the input's
// pieces, with images a.png, b.png and c.png beside it in images/.
#include "../support/fuzz_support.h"
#include "ffloc/data/dataset.h"

using namespace ffloc;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto& dir = fuzz::writeDatasetTree(
      data, size, {"sparse/0/cameras.txt", "sparse/0/images.txt", "sparse/0/points3D.txt", "split_query.txt"},
      {"images/a.png", "images/b.png", "images/c.png"});
  fuzz::expectOnlyInputErrors([&] { loadDataset(dir, "colmap"); });
  return 0;
}
