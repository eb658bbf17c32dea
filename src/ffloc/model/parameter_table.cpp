#include "ffloc/model/parameter_table.h"

#include <ATen/ops/empty.h>
#include <ATen/ops/equal.h>
#include <ATen/ops/isfinite.h>

#include <map>
#include <set>
#include <stdexcept>

#include "ffloc/core/error.h"
#include "ffloc/model/tensor_conversion.h"

namespace ffloc {

void ParameterTable::add(const std::string& name, std::vector<int64_t> shape, at::Tensor* tensor) {
  keys_.push_back({name, entries_.size(), false});
  entries_.push_back({name, std::move(shape), tensor});
}

void ParameterTable::addAlias(const std::string& alias, const std::string& name) {
  for (size_t i = 0; i < entries_.size(); ++i) {
    if (entries_[i].name == name) {
      keys_.push_back({alias, i, true});
      return;
    }
  }
  throw std::logic_error("ParameterTable::addAlias: '" + name + "' is not registered");
}

std::string shapeString(at::IntArrayRef shape) {
  std::string text = "(";
  for (size_t i = 0; i < shape.size(); ++i) {
    if (i > 0) text += ", ";
    text += std::to_string(shape[i]);
  }
  return text + ")";
}

namespace {

bool isFloatWeight(DType dtype) {
  return dtype == DType::kF32 || dtype == DType::kF16 || dtype == DType::kBF16;
}

}  // namespace

void loadParameters(const ParameterTable& table, const TensorArchive& archive,
                    const ParameterLoadOptions& options) {
  const std::string file = archive.path().string();
  const auto fail = [&file](const std::string& key, const std::string& what) {
    throwInputError(file, 0, "tensor '" + key + "': " + what);
  };

  std::map<size_t, std::vector<std::string>> names_of_entry;
  std::set<std::string> known;
  for (const ParameterTable::Key& key : table.keys()) {
    names_of_entry[key.entry].push_back(key.name);
    known.insert(key.name);
  }
  const auto ignored = [&options](const std::string& name) {
    for (const std::string& prefix : options.ignored_prefixes) {
      if (name.rfind(prefix, 0) == 0) return true;
    }
    return false;
  };
  for (const std::string& name : archive.names()) {
    if (!known.count(name) && !ignored(name)) fail(name, "unexpected key (not a parameter of this model)");
  }

  const auto& entries = table.entries();
  for (size_t i = 0; i < entries.size(); ++i) {
    const ParameterTable::Entry& entry = entries[i];
    at::Tensor value;
    std::string value_name;
    for (const std::string& name : names_of_entry[i]) {
      if (!archive.contains(name)) continue;
      const TensorView& view = archive.at(name);
      if (!isFloatWeight(view.dtype)) {
        // F64 was called "not a floating-point weight type", though convert writes it.
        fail(name, std::string("dtype ") + toString(view.dtype) +
                       " is not one a model loads (F32, F16 or BF16); 'ffloc convert --dtype f32' writes one");
      }
      if (at::IntArrayRef(view.shape) != at::IntArrayRef(entry.shape)) {
        fail(name, "shape " + view.shapeString() + " does not match the model's " +
                       shapeString(entry.shape));
      }
      at::Tensor converted = toTorch(view).to(options.dtype);
      // A network with NaN weights answers NaN everywhere: all-NaN weights built a map, and
      // localized against it, without a word.
      const int64_t non_finite = converted.numel() - at::isfinite(converted).sum().item<int64_t>();
      if (non_finite > 0) {
        fail(name, std::to_string(non_finite) + " of its " + std::to_string(converted.numel()) +
                       " values are not finite (NaN or infinite)");
      }
      if (value.defined()) {
        if (!at::equal(value, converted)) {
          fail(name, "differs from '" + value_name + "', which names the same tensor");
        }
        continue;
      }
      value = std::move(converted);
      value_name = name;
    }
    if (!value.defined()) {
      std::string names;
      for (const std::string& name : names_of_entry[i]) names += (names.empty() ? "" : "' or '") + name;
      throwInputError(file, 0, "tensor '" + names + "': missing (model expects shape " +
                                   shapeString(entry.shape) + ")");
    }
    *entry.tensor = std::move(value);
  }
}

void allocateParameters(const ParameterTable& table, const at::TensorOptions& options) {
  for (const ParameterTable::Entry& entry : table.entries()) {
    *entry.tensor = at::empty(entry.shape, options);
  }
}

}  // namespace ffloc
