#pragma once

#include <ATen/core/Tensor.h>

#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "ffloc/io/tensor_archive.h"

namespace ffloc {

// The torch element type of a stored dtype; InputError naming `what` for a dtype value outside
// the enum (a corrupt view).
at::ScalarType torchScalarType(DType dtype, const std::string& what);

// A CPU tensor owning a copy of the view's bytes (so it outlives the archive), with the view's
// dtype and shape. Handles F32, F16, BF16, F64, I64, I32, I16, I8, U8 and BOOL.
at::Tensor toTorch(const TensorView& view);

// Writes named tensors as float32 safetensors (writeSafetensors: atomic), with `metadata` and the
// checksums of both (io/tensor_checksums.h): the models and optimiser states that training writes,
// which every reader verifies.
void writeFloatTensors(const std::filesystem::path& path, const std::vector<std::pair<std::string, at::Tensor>>& tensors,
                       const std::map<std::string, std::string>& metadata);

}  // namespace ffloc
