#include <cstring>
#include <deque>
#include <limits>
#include <optional>
#include <unordered_map>

#include "ffloc/core/error.h"
#include "ffloc/io/mapped_file.h"
#include "ffloc/io/pickle.h"
#include "ffloc/io/tensor_archive.h"
#include "ffloc/io/zip_reader.h"

namespace ffloc {
namespace {

using pickle::Kind;
using pickle::Value;

std::optional<DType> storageDType(const std::string& global) {
  static const std::unordered_map<std::string, DType> kStorages = {
      {"torch.FloatStorage", DType::kF32},  {"torch.HalfStorage", DType::kF16},
      {"torch.BFloat16Storage", DType::kBF16}, {"torch.DoubleStorage", DType::kF64},
      {"torch.LongStorage", DType::kI64},   {"torch.IntStorage", DType::kI32},
      {"torch.ShortStorage", DType::kI16},  {"torch.CharStorage", DType::kI8},
      {"torch.ByteStorage", DType::kU8},    {"torch.BoolStorage", DType::kBool},
  };
  const auto found = kStorages.find(global);
  if (found == kStorages.end()) return std::nullopt;
  return found->second;
}

struct Storage {
  DType dtype;
  const uint8_t* data;
  uint64_t numel;
};

class PytorchCheckpointArchive : public TensorArchive {
 public:
  explicit PytorchCheckpointArchive(const std::filesystem::path& path);

 private:
  [[noreturn]] void fail(const std::string& what) const { throwInputError(path_.string(), 0, what); }
  [[noreturn]] void failTensor(const std::string& name, const std::string& what) const {
    fail("tensor '" + name + "': " + what);
  }
  // nullopt when `value` is not a tensor (a non-tensor entry of the state dict).
  std::optional<TensorView> resolveTensor(const std::string& name, const Value* value, int depth);
  TensorView rebuildTensor(const std::string& name, const std::vector<const Value*>& arguments);
  const Storage& loadStorage(const std::string& name, const Value* reference);
  std::vector<int64_t> readIntTuple(const std::string& name, const char* field, const Value* value) const;

  MappedFile file_;
  std::optional<ZipReader> zip_;
  std::string prefix_;  // "<archive name>/", taken from the data.pkl record
  std::unordered_map<std::string, Storage> storages_;
  // Gathered copies of non-contiguous tensors, which cannot be views into the file.
  std::deque<std::vector<uint8_t>> copies_;
  uint64_t copied_bytes_ = 0;
};

PytorchCheckpointArchive::PytorchCheckpointArchive(const std::filesystem::path& path) : file_(path) {
  path_ = path;
  zip_.emplace(file_.data(), file_.size(), path.string());

  // torch.save() names every record "<archive name>/...", the archive name being the saved
  // file's stem at the time; the pickle is the shallowest "data.pkl".
  const ZipEntry* pickle_entry = nullptr;
  for (const ZipEntry& entry : zip_->entries()) {
    const std::string& name = entry.name;
    const bool is_pickle = name == "data.pkl" ||
                           (name.size() > 9 && name.compare(name.size() - 9, 9, "/data.pkl") == 0);
    if (is_pickle && (!pickle_entry || name.size() < pickle_entry->name.size())) pickle_entry = &entry;
  }
  if (!pickle_entry) fail("zip archive has no data.pkl record; not a torch.save() checkpoint");
  prefix_ = pickle_entry->name.substr(0, pickle_entry->name.size() - 8);

  if (const ZipEntry* byteorder = zip_->find(prefix_ + "byteorder")) {
    const uint8_t* bytes = zip_->storedData(*byteorder);
    const std::string order(reinterpret_cast<const char*>(bytes), byteorder->uncompressed_size);
    if (order != "little") fail("byteorder record says '" + order + "'; only little-endian is supported");
  }

  const pickle::Unpickled unpickled =
      pickle::unpickle(zip_->storedData(*pickle_entry), pickle_entry->uncompressed_size,
                       path.string() + ": " + pickle_entry->name);
  const Value* root = unpickled.root;
  if (root->kind != Kind::kDict) fail("the pickled top-level object is not a dict");
  const Value* state_dict = root;
  for (const char* key : {"model", "state_dict"}) {
    const Value* nested = pickle::dictGet(root, key);
    if (nested && nested->kind == Kind::kDict) {
      state_dict = nested;
      break;
    }
  }

  for (const auto& [key, value] : state_dict->entries) {
    if (key->kind != Kind::kString) continue;
    std::optional<TensorView> view = resolveTensor(key->text, value, 0);
    if (!view) continue;
    // A key pickled twice keeps its first position and its last value, as a Python dict does.
    const auto [slot, inserted] = tensors_.insert_or_assign(key->text, std::move(*view));
    if (inserted) names_.push_back(slot->first);
  }
  if (names_.empty()) fail("no tensors found in the checkpoint's state dict");
}

std::optional<TensorView> PytorchCheckpointArchive::resolveTensor(const std::string& name,
                                                                  const Value* value, int depth) {
  if (value->kind != Kind::kObject || !value->callable || value->callable->kind != Kind::kGlobal) {
    return std::nullopt;
  }
  if (depth > 4) failTensor(name, "tensor rebuild calls nested too deeply");
  const std::string& function = value->callable->text;
  const std::vector<const Value*>& arguments = value->items;
  if (function == "torch._utils._rebuild_tensor_v2" || function == "torch._utils._rebuild_tensor") {
    return rebuildTensor(name, arguments);
  }
  // nn.Parameter wraps the data tensor: (data, requires_grad, backward_hooks[, state]).
  if (function == "torch._utils._rebuild_parameter" ||
      function == "torch._utils._rebuild_parameter_with_state") {
    if (arguments.empty()) failTensor(name, function + " without arguments");
    return resolveTensor(name, arguments[0], depth + 1);
  }
  // Tensor subclasses: (function, type, function arguments, state).
  if (function == "torch._tensor._rebuild_from_type_v2") {
    if (arguments.size() < 3 || arguments[2]->kind != Kind::kTuple) {
      failTensor(name, function + " with malformed arguments");
    }
    Value inner;
    inner.kind = Kind::kObject;
    inner.callable = arguments[0];
    inner.items = arguments[2]->items;
    return resolveTensor(name, &inner, depth + 1);
  }
  if (function.rfind("torch._utils._rebuild_", 0) == 0) {
    failTensor(name, "unsupported tensor kind " + function + " (sparse, quantized or meta tensor)");
  }
  return std::nullopt;
}

std::vector<int64_t> PytorchCheckpointArchive::readIntTuple(const std::string& name,
                                                            const char* field,
                                                            const Value* value) const {
  if (value->kind != Kind::kTuple && value->kind != Kind::kList) {
    failTensor(name, std::string(field) + " is not a tuple");
  }
  std::vector<int64_t> numbers;
  for (const Value* item : value->items) {
    if (item->kind != Kind::kInt || item->integer < 0) {
      failTensor(name, std::string(field) + " holds a value that is not a non-negative integer");
    }
    numbers.push_back(item->integer);
  }
  return numbers;
}

TensorView PytorchCheckpointArchive::rebuildTensor(const std::string& name,
                                                   const std::vector<const Value*>& arguments) {
  // (storage, storage_offset, size, stride, ...): requires_grad, hooks and metadata are unused.
  if (arguments.size() < 4) failTensor(name, "tensor rebuild with fewer than 4 arguments");
  const Storage& storage = loadStorage(name, arguments[0]);
  if (arguments[1]->kind != Kind::kInt || arguments[1]->integer < 0) {
    failTensor(name, "storage offset is not a non-negative integer");
  }
  const uint64_t offset = static_cast<uint64_t>(arguments[1]->integer);
  TensorView view;
  view.name = name;
  view.dtype = storage.dtype;
  view.shape = readIntTuple(name, "size", arguments[2]);
  const std::vector<int64_t> stride = readIntTuple(name, "stride", arguments[3]);
  if (stride.size() != view.shape.size()) failTensor(name, "size and stride differ in length");

  uint64_t numel = 1;
  for (int64_t extent : view.shape) {
    if (__builtin_mul_overflow(numel, static_cast<uint64_t>(extent), &numel) ||
        numel > static_cast<uint64_t>(std::numeric_limits<int64_t>::max())) {
      failTensor(name, "size " + view.shapeString() + " overflows the element count");
    }
  }
  const uint64_t element_size = elementSize(storage.dtype);
  if (numel == 0) {
    view.data = storage.data;
    return view;
  }
  // Highest element index the view touches; strides are non-negative.
  uint64_t last = offset;
  for (size_t i = 0; i < stride.size(); ++i) {
    uint64_t reach = 0;
    if (__builtin_mul_overflow(static_cast<uint64_t>(view.shape[i] - 1),
                               static_cast<uint64_t>(stride[i]), &reach) ||
        __builtin_add_overflow(last, reach, &last)) {
      failTensor(name, "size and stride overflow");
    }
  }
  if (last >= storage.numel) {
    failTensor(name, "view " + view.shapeString() + " at offset " + std::to_string(offset) +
                         " reaches element " + std::to_string(last) + " of a storage of " +
                         std::to_string(storage.numel));
  }
  bool contiguous = true;
  uint64_t expected = 1;
  for (size_t i = view.shape.size(); i-- > 0;) {
    if (view.shape[i] != 1 && static_cast<uint64_t>(stride[i]) != expected) contiguous = false;
    expected *= static_cast<uint64_t>(view.shape[i]);
  }
  view.nbytes = static_cast<size_t>(numel * element_size);
  if (contiguous) {
    view.data = storage.data + offset * element_size;
    return view;
  }
  // Zero strides (expanded tensors) can describe far more elements than are stored, and many
  // names can view one storage: the copies together must not outgrow the file.
  if (numel > (file_.size() - copied_bytes_) / element_size) {
    failTensor(name, "non-contiguous view " + view.shapeString() +
                         (copied_bytes_ > 0 ? ", with the copies before it, is" : " is") + " larger than the file");
  }
  copied_bytes_ += view.nbytes;
  std::vector<uint8_t>& copy = copies_.emplace_back(view.nbytes);
  std::vector<int64_t> index(view.shape.size(), 0);
  uint64_t source = offset;
  for (uint64_t n = 0; n < numel; ++n) {
    std::memcpy(copy.data() + n * element_size, storage.data + source * element_size, element_size);
    for (size_t d = index.size(); d-- > 0;) {
      if (++index[d] < view.shape[d]) {
        source += static_cast<uint64_t>(stride[d]);
        break;
      }
      source -= static_cast<uint64_t>(stride[d]) * static_cast<uint64_t>(view.shape[d] - 1);
      index[d] = 0;
    }
  }
  view.data = copy.data();
  return view;
}

const Storage& PytorchCheckpointArchive::loadStorage(const std::string& name, const Value* reference) {
  // Persistent id ('storage', storage type, key, location, numel).
  if (reference->kind != Kind::kPersistentId || reference->persistent_id->kind != Kind::kTuple ||
      reference->persistent_id->items.size() < 5 ||
      !pickle::isString(reference->persistent_id->items[0], "storage")) {
    failTensor(name, "storage is not a ('storage', type, key, location, numel) persistent id");
  }
  const std::vector<const Value*>& fields = reference->persistent_id->items;
  if (fields[1]->kind != Kind::kGlobal) failTensor(name, "storage type is not a class");
  const std::optional<DType> dtype = storageDType(fields[1]->text);
  if (!dtype) failTensor(name, "unsupported storage type " + fields[1]->text);
  if (fields[2]->kind != Kind::kString) failTensor(name, "storage key is not a string");
  if (fields[4]->kind != Kind::kInt || fields[4]->integer < 0) {
    failTensor(name, "storage size is not a non-negative integer");
  }
  const std::string& key = fields[2]->text;
  const auto cached = storages_.find(key);
  if (cached != storages_.end()) {
    if (cached->second.dtype != *dtype) failTensor(name, "storage " + key + " used with two dtypes");
    return cached->second;
  }
  const std::string record = prefix_ + "data/" + key;
  const ZipEntry* entry = zip_->find(record);
  if (!entry) failTensor(name, "storage record '" + record + "' missing from the archive");
  const uint64_t numel = static_cast<uint64_t>(fields[4]->integer);
  if (numel > entry->uncompressed_size / elementSize(*dtype)) {
    failTensor(name, "storage '" + record + "' holds " + std::to_string(entry->uncompressed_size) +
                         " bytes, fewer than " + std::to_string(numel) + " " + toString(*dtype) +
                         " elements");
  }
  const Storage storage{*dtype, zip_->storedData(*entry), numel};
  return storages_.emplace(key, storage).first->second;
}

}  // namespace

std::unique_ptr<TensorArchive> openPytorchCheckpoint(const std::filesystem::path& path) {
  return std::make_unique<PytorchCheckpointArchive>(path);
}

}  // namespace ffloc
