// Map files, twice per input. First the input as it is: container, metadata JSON and
// checksums. Most mutations then stop at a checksum, so the input is also re-sealed (every
// checksum recomputed, the file written again with our writer) and read once more, which takes
// the fuzzer into the checks of poses, intrinsics, geometry, grids and tensor shapes.
#include <nlohmann/json.hpp>

#include "../support/fuzz_support.h"
#include "ffloc/core/error.h"
#include "ffloc/core/hash.h"
#include "ffloc/io/map_file.h"
#include "ffloc/io/tensor_archive.h"

using namespace ffloc;

namespace {

// The input's tensors and metadata with every checksum made right; false when the input is not
// a container with a JSON object as its map metadata.
bool reseal(const std::filesystem::path& input, const std::filesystem::path& output) {
  std::unique_ptr<TensorArchive> archive;
  nlohmann::json description;
  try {
    archive = openSafetensors(input);
    description = readMapMetadata(*archive, input.string());
  } catch (const InputError&) {
    return false;
  }
  if (!description.is_object()) return false;
  std::vector<TensorView> tensors;
  nlohmann::json checksums = nlohmann::json::object();
  for (const std::string& name : archive->names()) {
    const TensorView& view = archive->at(name);
    tensors.push_back(view);
    checksums[name] = hex64(fnv1a64(view.data, view.nbytes));
  }
  description["checksums"] = checksums;
  writeSafetensors(output, tensors, mapMetadataEntries(description, output.string()));
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const fuzz::ScratchFolder& folder = fuzz::scratchFolder();
  folder.clear();
  const std::filesystem::path input = folder.path() / "map.safetensors";
  const std::filesystem::path resealed = folder.path() / "resealed.safetensors";
  folder.write(input.filename().string(), std::string_view(reinterpret_cast<const char*>(data), size));
  fuzz::expectOnlyInputErrors([&] { readMapHeader(input); });
  fuzz::expectOnlyInputErrors([&] { readMapFile(input); });
  fuzz::expectOnlyInputErrors([&] {
    if (reseal(input, resealed)) readMapFile(resealed);
  });
  return 0;
}
