#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "ffloc/io/pickle.h"

// Hand-made torch.save() archives: the checkpoint tests build layouts the real fixture lacks
// (plain state dicts, strided views, other dtypes, damage) with these, and the fuzzers write
// their seeds and wrap fuzzed pickles with them.
namespace ffloc::testing {

// `bytes` little-endian bytes of `value`.
void appendLe(std::string* out, uint64_t value, int bytes);

// pickle::Writer with what else torch.save() pickles: globals, tuples of ints, tensors.
struct PickleWriter : pickle::Writer {
  void global(const std::string& module, const std::string& name);
  void ints(const std::vector<int>& values);
  // torch._utils._rebuild_tensor_v2 of a view into the storage `key`.
  void tensor(const std::string& storage_type, const std::string& key, int storage_numel, int offset,
              const std::vector<int>& size, const std::vector<int>& stride);
};

struct ZipMember {
  std::string name;
  std::string data;
  uint16_t method = 0;
};

// A zip archive of stored members; with zip64, every size and offset goes through the zip64
// extra field and end records, as for a checkpoint beyond 4 GB.
std::string makeZip(const std::vector<ZipMember>& members, bool zip64);

}  // namespace ffloc::testing
