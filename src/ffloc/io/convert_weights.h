#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>

#include "ffloc/io/tensor_archive.h"

namespace ffloc {

struct ConvertWeightsOptions {
  // Floating-point tensors are stored as this dtype (F32, F16, BF16 or F64); nullopt keeps each
  // tensor's own dtype. Integer and bool tensors are never cast.
  std::optional<DType> float_dtype;
  bool quiet = false;  // no progress bar on stderr
};

struct ConvertWeightsSummary {
  size_t tensors_read = 0;
  size_t tensors_written = 0;
  size_t aliases_dropped = 0;  // names that shared their bytes with a kept name
  uint64_t bytes_written = 0;  // tensor data, header excluded
};

// Converts any archive openTensorArchive() reads (a torch.save() checkpoint or a safetensors
// file) into a safetensors file in the Hugging Face hub layout: tensors in name order, exact
// aliases (names sharing the same bytes, dtype and shape) stored once under the
// lexicographically first name, metadata {"format": "pt", "source": <input file name>} on top
// of the input's own metadata. An input that carries checksums (io/tensor_checksums.h: training's
// models) is verified first, and the output carries checksums of its own. The output is written
// atomically.
ConvertWeightsSummary convertWeights(const std::filesystem::path& input,
                                     const std::filesystem::path& output,
                                     const ConvertWeightsOptions& options = {});

// "f32", "f16", "bf16", "f64" (any case) to the dtype; InputError naming `field` otherwise.
DType parseFloatDType(const std::string& text, const std::string& field);

}  // namespace ffloc
