#pragma once

#include <ATen/core/Tensor.h>

#include <string>
#include <vector>

#include "ffloc/io/tensor_archive.h"

namespace ffloc {

// The state_dict of a functional model: every parameter's PyTorch name and shape, and where its
// tensor lives in the model. Modules register their own tensors, so the table is rebuilt on
// demand and never outlives the model it points into.
class ParameterTable {
 public:
  struct Entry {
    std::string name;
    std::vector<int64_t> shape;
    at::Tensor* tensor = nullptr;
  };
  // One state_dict key; an alias names the same tensor as an earlier entry (PyTorch keeps both
  // names when two modules share a parameter).
  struct Key {
    std::string name;
    size_t entry = 0;
    bool is_alias = false;
  };

  void add(const std::string& name, std::vector<int64_t> shape, at::Tensor* tensor);
  // `alias` is another state_dict name of the already registered `name`.
  void addAlias(const std::string& alias, const std::string& name);

  const std::vector<Entry>& entries() const { return entries_; }
  // Every key in state_dict order, aliases included.
  const std::vector<Key>& keys() const { return keys_; }

 private:
  std::vector<Entry> entries_;
  std::vector<Key> keys_;
};

struct ParameterLoadOptions {
  at::ScalarType dtype = at::kFloat;  // every loaded tensor is converted to this
  // Archive keys starting with one of these are skipped instead of reported as unexpected (e.g.
  // the second DUSt3R head when FastForward is initialised from DUSt3R).
  std::vector<std::string> ignored_prefixes;
};

// Fills every entry from `archive`, strictly: InputError naming the file and key for a missing
// key, an unexpected key, a shape mismatch (both shapes) or a non-float dtype. F32, F16 and BF16
// are accepted and converted to options.dtype. An aliased tensor may be stored under either
// name or both (then the copies must be equal).
void loadParameters(const ParameterTable& table, const TensorArchive& archive,
                    const ParameterLoadOptions& options = {});

// Gives every entry an uninitialised tensor of its shape (at::kMeta allocates nothing).
void allocateParameters(const ParameterTable& table, const at::TensorOptions& options);

std::string shapeString(at::IntArrayRef shape);

}  // namespace ffloc
