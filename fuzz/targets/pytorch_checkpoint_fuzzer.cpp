// The .pth reader past the zip layer: the input is the pickle of a torch.save() archive whose
// other records are fixed (two storages and the byte order), so the fuzzer spends its time on
// how the pickled state dict names tensors, storages, offsets, sizes and strides.
#include "../support/fuzz_support.h"
#include "ffloc/io/tensor_archive.h"
#include "ffloc/io/testing/torch_save_writer.h"

using namespace ffloc;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string floats(64, '\x01');  // storage "0": 16 F32 or 32 F16 values
  static const std::string bytes(16, '\x02');   // storage "1"
  const std::string pickle(reinterpret_cast<const char*>(data), size);
  const fuzz::ScratchFolder& folder = fuzz::scratchFolder();
  folder.clear();
  folder.write("checkpoint.pth", testing::makeZip({{"archive/data.pkl", pickle},
                                                   {"archive/byteorder", "little"},
                                                   {"archive/data/0", floats},
                                                   {"archive/data/1", bytes}},
                                                  false));
  fuzz::expectOnlyInputErrors([&] {
    const auto archive = openPytorchCheckpoint(folder.path() / "checkpoint.pth");
    for (const std::string& name : archive->names()) {
      const TensorView& view = archive->at(name);
      fuzz::touch(view.data, view.nbytes);
    }
  });
  return 0;
}
