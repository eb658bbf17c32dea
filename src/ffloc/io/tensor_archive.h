#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "ffloc/io/mapped_file.h"

namespace ffloc {

// Element types of stored tensors (safetensors names: F32, F16, BF16, F64, I64, I32, I16, I8,
// U8, BOOL).
enum class DType { kF32, kF16, kBF16, kF64, kI64, kI32, kI16, kI8, kU8, kBool };
const char* toString(DType dtype);
size_t elementSize(DType dtype);
// The dtype whose safetensors name is `name` ("F32", ...); nullopt when there is none.
std::optional<DType> dtypeFromString(const std::string& name);
// F32, F16, BF16 and F64.
bool isFloatingPoint(DType dtype);

// A read-only view of one stored tensor: little-endian, C-order, contiguous. `data` points into
// the archive's memory (usually a memory map) and lives as long as the archive. `data` is not
// necessarily aligned to the element size (a safetensors header need not be padded), so read
// elements with memcpy or through toFloat32() (half.h). nbytes == numel() * elementSize(dtype).
struct TensorView {
  std::string name;
  DType dtype = DType::kF32;
  std::vector<int64_t> shape;
  const uint8_t* data = nullptr;
  size_t nbytes = 0;

  int64_t numel() const;
  std::string shapeString() const;  // "(2, 3, 4)"
};

// A named collection of tensors read from a weights file (safetensors or a PyTorch .pth
// checkpoint), validated on open: a truncated or malicious file raises InputError naming the
// file and the field, never a crash or an unbounded allocation.
class TensorArchive {
 public:
  virtual ~TensorArchive() = default;

  const std::filesystem::path& path() const { return path_; }
  // Tensor names in file order: for safetensors the order of the data in the file, for a
  // checkpoint the order of the pickled state dict.
  const std::vector<std::string>& names() const { return names_; }
  bool contains(const std::string& name) const { return tensors_.count(name) != 0; }
  // InputError "<file>: tensor '<name>': missing" when absent.
  const TensorView& at(const std::string& name) const;
  // safetensors __metadata__ (string to string); for .pth, empty.
  const std::map<std::string, std::string>& metadata() const { return metadata_; }

 protected:
  std::filesystem::path path_;
  std::vector<std::string> names_;
  std::map<std::string, TensorView> tensors_;
  std::map<std::string, std::string> metadata_;
};

// Opens by content (safetensors header or zip magic), whatever the extension.
std::unique_ptr<TensorArchive> openTensorArchive(const std::filesystem::path& path);
// Views into the file as mapped, or into a snapshot of it (mapped_file.h).
std::unique_ptr<TensorArchive> openSafetensors(const std::filesystem::path& path, FileMapping mapping = FileMapping::kFile);
// A zip-format torch.save() checkpoint. When the pickled top-level object is a dict holding a
// state dict under "model" (DUSt3R's official layout, with a non-tensor "args"), the archive
// exposes that state dict; a plain state dict is exposed as it is. Names that share a storage
// (aliases) all appear, pointing at the same bytes. A "state_dict" entry (Lightning) is used like
// "model". Non-contiguous tensors are gathered into C-order copies held by the archive; all
// others are views into the memory-mapped file. Details and limits: docs/weights.md.
std::unique_ptr<TensorArchive> openPytorchCheckpoint(const std::filesystem::path& path);

// Called after each tensor written with the number written so far.
using WriteProgress = std::function<void(std::size_t tensors_written)>;

// Writes a safetensors file atomically (a temporary file beside it, then rename), tensors in the
// given order, metadata under __metadata__; the header is padded with spaces to a multiple of 8
// bytes so that every tensor starts 8-byte aligned when the tensors' sizes are multiples of 8.
// InputError naming the file (and the tensor) for duplicate or empty names, a view whose nbytes
// does not match its shape and dtype, or a write failure; the target is then left untouched.
void writeSafetensors(const std::filesystem::path& path, const std::vector<TensorView>& tensors,
                      const std::map<std::string, std::string>& metadata = {},
                      const WriteProgress& progress = nullptr);

}  // namespace ffloc
