// The zip reader behind .pth checkpoints, on the input as an archive held in memory: its
// directory, then every member's stored bytes.
#include "../support/fuzz_support.h"
#include "ffloc/io/zip_reader.h"

using namespace ffloc;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  fuzz::expectOnlyInputErrors([&] {
    const ZipReader zip(data, size, "fuzz.zip");
    for (const ZipEntry& entry : zip.entries()) {
      if (zip.find(entry.name) == nullptr) std::abort();
      // Each member on its own: a compressed or damaged one does not hide the others.
      fuzz::expectOnlyInputErrors([&] { fuzz::touch(zip.storedData(entry), entry.compressed_size); });
    }
  });
  return 0;
}
