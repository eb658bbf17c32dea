#include "ffloc/io/testing/torch_save_writer.h"

namespace ffloc::testing {

void appendLe(std::string* out, uint64_t value, int bytes) {
  for (int i = 0; i < bytes; ++i) out->push_back(static_cast<char>((value >> (8 * i)) & 0xff));
}

void PickleWriter::global(const std::string& module, const std::string& name) {
  op('c');
  bytes += module + "\n" + name + "\n";
}

void PickleWriter::ints(const std::vector<int>& values) {
  op('(');
  for (int value : values) integer(value);
  op('t');
}

void PickleWriter::tensor(const std::string& storage_type, const std::string& key, int storage_numel, int offset,
                          const std::vector<int>& size, const std::vector<int>& stride) {
  global("torch._utils", "_rebuild_tensor_v2");
  op('(');
  op('(');
  text("storage");
  global("torch", storage_type);
  text(key);
  text("cpu");
  integer(storage_numel);
  op('t');
  op('Q');
  integer(offset);
  ints(size);
  ints(stride);
  op('\x89');
  global("collections", "OrderedDict");
  op(')');
  op('R');
  op('t');
  op('R');
}

std::string makeZip(const std::vector<ZipMember>& members, bool zip64) {
  std::string out, directory;
  for (const ZipMember& member : members) {
    const uint64_t offset = out.size();
    appendLe(&out, 0x04034b50, 4);
    appendLe(&out, 20, 2);
    appendLe(&out, 0, 2);
    appendLe(&out, member.method, 2);
    appendLe(&out, 0, 4);  // time, date
    appendLe(&out, 0, 4);  // crc (not checked)
    appendLe(&out, member.data.size(), 4);
    appendLe(&out, member.data.size(), 4);
    appendLe(&out, member.name.size(), 2);
    appendLe(&out, 3, 2);
    out += member.name + "abc";  // an unknown extra field moves the data
    out += member.data;

    appendLe(&directory, 0x02014b50, 4);
    appendLe(&directory, 45, 2);
    appendLe(&directory, 45, 2);
    appendLe(&directory, 0, 2);
    appendLe(&directory, member.method, 2);
    appendLe(&directory, 0, 4);
    appendLe(&directory, 0, 4);
    appendLe(&directory, zip64 ? 0xffffffff : member.data.size(), 4);
    appendLe(&directory, zip64 ? 0xffffffff : member.data.size(), 4);
    appendLe(&directory, member.name.size(), 2);
    appendLe(&directory, zip64 ? 28 : 0, 2);
    appendLe(&directory, 0, 2);
    appendLe(&directory, 0, 2);
    appendLe(&directory, 0, 2);
    appendLe(&directory, 0, 4);
    appendLe(&directory, zip64 ? 0xffffffff : offset, 4);
    directory += member.name;
    if (zip64) {
      appendLe(&directory, 0x0001, 2);
      appendLe(&directory, 24, 2);
      appendLe(&directory, member.data.size(), 8);
      appendLe(&directory, member.data.size(), 8);
      appendLe(&directory, offset, 8);
    }
  }
  const uint64_t directory_offset = out.size();
  out += directory;
  if (zip64) {
    const uint64_t record = out.size();
    appendLe(&out, 0x06064b50, 4);
    appendLe(&out, 44, 8);
    appendLe(&out, 45, 2);
    appendLe(&out, 45, 2);
    appendLe(&out, 0, 8);
    appendLe(&out, members.size(), 8);
    appendLe(&out, members.size(), 8);
    appendLe(&out, directory.size(), 8);
    appendLe(&out, directory_offset, 8);
    appendLe(&out, 0x07064b50, 4);
    appendLe(&out, 0, 4);
    appendLe(&out, record, 8);
    appendLe(&out, 1, 4);
  }
  appendLe(&out, 0x06054b50, 4);
  appendLe(&out, 0, 4);
  appendLe(&out, zip64 ? 0xffff : members.size(), 2);
  appendLe(&out, zip64 ? 0xffff : members.size(), 2);
  appendLe(&out, zip64 ? 0xffffffff : directory.size(), 4);
  appendLe(&out, zip64 ? 0xffffffff : directory_offset, 4);
  appendLe(&out, 0, 2);
  return out;
}

}  // namespace ffloc::testing
