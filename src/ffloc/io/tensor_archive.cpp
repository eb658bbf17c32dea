#include "ffloc/io/tensor_archive.h"

#include <algorithm>
#include <cstring>

#include "ffloc/core/error.h"
#include "ffloc/io/mapped_file.h"

// Stored tensors are little-endian and are handed out as raw views.
static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "ffloc's weights I/O needs a little-endian host");

namespace ffloc {
namespace {

struct DTypeInfo {
  DType dtype;
  const char* name;
  size_t size;
};

constexpr DTypeInfo kDTypes[] = {
    {DType::kF32, "F32", 4}, {DType::kF16, "F16", 2}, {DType::kBF16, "BF16", 2},
    {DType::kF64, "F64", 8}, {DType::kI64, "I64", 8}, {DType::kI32, "I32", 4},
    {DType::kI16, "I16", 2}, {DType::kI8, "I8", 1},   {DType::kU8, "U8", 1},
    {DType::kBool, "BOOL", 1},
};

const DTypeInfo& info(DType dtype) {
  for (const DTypeInfo& entry : kDTypes) {
    if (entry.dtype == dtype) return entry;
  }
  return kDTypes[0];
}

}  // namespace

const char* toString(DType dtype) { return info(dtype).name; }

size_t elementSize(DType dtype) { return info(dtype).size; }

std::optional<DType> dtypeFromString(const std::string& name) {
  for (const DTypeInfo& entry : kDTypes) {
    if (name == entry.name) return entry.dtype;
  }
  return std::nullopt;
}

bool isFloatingPoint(DType dtype) {
  return dtype == DType::kF32 || dtype == DType::kF16 || dtype == DType::kBF16 ||
         dtype == DType::kF64;
}

int64_t TensorView::numel() const {
  int64_t count = 1;
  for (int64_t dim : shape) count *= dim;
  return count;
}

std::string TensorView::shapeString() const {
  std::string text = "(";
  for (size_t i = 0; i < shape.size(); ++i) {
    if (i > 0) text += ", ";
    text += std::to_string(shape[i]);
  }
  return text + ")";
}

const TensorView& TensorArchive::at(const std::string& name) const {
  const auto found = tensors_.find(name);
  if (found == tensors_.end()) throwInputError(path_.string(), 0, "tensor '" + name + "': missing");
  return found->second;
}

std::unique_ptr<TensorArchive> openTensorArchive(const std::filesystem::path& path) {
  // Sniff the first bytes only; the format reader maps the file again, which is cheap.
  uint8_t head[9] = {};
  size_t size = 0;
  {
    const MappedFile file(path);
    size = file.size();
    if (size > 0) std::memcpy(head, file.data(), std::min(size, sizeof(head)));
  }
  if (size >= 4 && head[0] == 'P' && head[1] == 'K' && head[2] == 3 && head[3] == 4) {
    return openPytorchCheckpoint(path);
  }
  if (size >= 2 && head[0] == 0x80 && head[1] <= 5) {
    throwInputError(path.string(), 0,
                    "legacy (pre-1.6, non-zip) torch.save format is not supported; re-save it "
                    "with torch.save(..., _use_new_zipfile_serialization=True)");
  }
  // The smallest weights file, a safetensors file without tensors, is an 8-byte length and "{}".
  if (size < 10) {
    throwInputError(path.string(), 0,
                    "file too short (" + std::to_string(size) + " bytes) for a safetensors file or a PyTorch checkpoint");
  }
  if (head[8] == '{') return openSafetensors(path);
  throwInputError(path.string(), 0,
                  "unrecognised weights format (neither a safetensors header nor a zip-format "
                  "PyTorch checkpoint)");
}

}  // namespace ffloc
