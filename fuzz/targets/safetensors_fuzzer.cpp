// The weights-file entry point: openTensorArchive sniffs the format, then the safetensors header
// (JSON) and tensor table are validated; every tensor it hands out is read to its last byte.
#include "../support/fuzz_support.h"
#include "ffloc/io/tensor_archive.h"

using namespace ffloc;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const fuzz::ScratchFolder& folder = fuzz::scratchFolder();
  folder.clear();
  folder.write("weights.safetensors", std::string_view(reinterpret_cast<const char*>(data), size));
  fuzz::expectOnlyInputErrors([&] {
    const auto archive = openTensorArchive(folder.path() / "weights.safetensors");
    for (const std::string& name : archive->names()) {
      const TensorView& view = archive->at(name);
      fuzz::touch(view.data, view.nbytes);
    }
  });
  return 0;
}
