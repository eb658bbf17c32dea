#include "ffloc/model/tensor_conversion.h"

#include <ATen/ops/empty.h>

#include <cstring>

#include "ffloc/core/error.h"
#include "ffloc/io/tensor_archive.h"
#include "ffloc/io/tensor_checksums.h"

namespace ffloc {

at::ScalarType torchScalarType(DType dtype, const std::string& what) {
  switch (dtype) {
    case DType::kF32: return at::kFloat;
    case DType::kF16: return at::kHalf;
    case DType::kBF16: return at::kBFloat16;
    case DType::kF64: return at::kDouble;
    case DType::kI64: return at::kLong;
    case DType::kI32: return at::kInt;
    case DType::kI16: return at::kShort;
    case DType::kI8: return at::kChar;
    case DType::kU8: return at::kByte;
    case DType::kBool: return at::kBool;
  }
  throwInputError(what, 0, "unsupported dtype");
}

at::Tensor toTorch(const TensorView& view) {
  const at::ScalarType type = torchScalarType(view.dtype, "tensor '" + view.name + "'");
  at::Tensor tensor = at::empty(view.shape, at::TensorOptions().dtype(type));
  if (static_cast<size_t>(tensor.nbytes()) != view.nbytes) {
    throwInputError("tensor '" + view.name + "'", 0,
                    "holds " + std::to_string(view.nbytes) + " bytes but shape " +
                        view.shapeString() + " of " + toString(view.dtype) + " needs " +
                        std::to_string(tensor.nbytes()));
  }
  // A copy rather than from_blob: archive data may be unaligned and must not be kept alive.
  if (view.nbytes > 0) std::memcpy(tensor.data_ptr(), view.data, view.nbytes);
  return tensor;
}

// Float32 CPU copies kept alive while the views into them are written.
void writeFloatTensors(const std::filesystem::path& path, const std::vector<std::pair<std::string, at::Tensor>>& tensors,
                  const std::map<std::string, std::string>& metadata) {
  std::vector<at::Tensor> keep;
  std::vector<TensorView> views;
  keep.reserve(tensors.size());
  for (const auto& [name, tensor] : tensors) {
    keep.push_back(tensor.detach().to(at::kCPU, at::kFloat).contiguous());
    const at::Tensor& t = keep.back();
    TensorView view;
    view.name = name;
    view.dtype = DType::kF32;
    view.shape = t.sizes().vec();
    view.data = static_cast<const uint8_t*>(t.data_ptr());
    view.nbytes = static_cast<size_t>(t.numel()) * sizeof(float);
    views.push_back(view);
  }
  writeSafetensors(path, views, withChecksums(views, metadata));
}

}  // namespace ffloc
