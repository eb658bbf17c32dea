#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <vector>

#include "ffloc/core/error.h"
#include "ffloc/core/file_paths.h"
#include "ffloc/core/temporary_file.h"
#include "ffloc/core/utf8.h"
#include "ffloc/io/mapped_file.h"
#include "ffloc/io/tensor_archive.h"

namespace ffloc {
namespace {

// Not ordered_json: its linear key lookup makes parsing quadratic in the number of tensors, and
// it deep-copies values when growing. File order comes from data_offsets anyway.
using Json = nlohmann::json;

// A safetensors header is {name: {dtype, shape: [..], data_offsets: [..]}}: depth 3. Refusing
// deeper nesting bounds every recursive walk of the parsed value.
constexpr int kMaxHeaderDepth = 8;

// The reference implementation refuses headers above 100 MB; the official 2.2 GB DUSt3R
// checkpoint needs ~100 KB.
constexpr uint64_t kMaxHeaderBytes = 100ull << 20;

// A header's lists are shapes and data offsets, and its objects below the top tensor entries
// (three keys) and the metadata: a few values each. A list of 50 million zeros (100 MB of header)
// grew to 2.5 GB parsed before anything looked at it; both are bounded while parsing.
constexpr int kMaxHeaderListLength = 64;
constexpr int kMaxTensorEntryKeys = 16;

class SafetensorsArchive : public TensorArchive {
 public:
  SafetensorsArchive(const std::filesystem::path& path, FileMapping mapping);

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throwInputError(path_.string(), 0, what);
  }
  [[noreturn]] void failTensor(const std::string& name, const std::string& what) const {
    fail("tensor '" + name + "': " + what);
  }
  Json parseHeader(const char* text, size_t size) const;
  void readMetadata(const Json& value);
  // Byte range [begin, end) of the tensor relative to the data section.
  TensorView readTensor(const std::string& name, const Json& entry, uint64_t data_size,
                        const uint8_t* data_section, std::pair<uint64_t, uint64_t>* range) const;

  MappedFile file_;
};

uint64_t readLe64(const uint8_t* bytes) {
  uint64_t value = 0;
  for (int i = 7; i >= 0; --i) value = (value << 8) | bytes[i];
  return value;
}

void writeLe64(uint64_t value, uint8_t* bytes) {
  for (int i = 0; i < 8; ++i) bytes[i] = static_cast<uint8_t>(value >> (8 * i));
}

SafetensorsArchive::SafetensorsArchive(const std::filesystem::path& path, FileMapping mapping) : file_(path, mapping) {
  path_ = path;
  const uint64_t file_size = file_.size();
  if (file_size < 8) {
    fail("file too short for a safetensors header (" + std::to_string(file_size) + " bytes)");
  }
  const uint64_t header_size = readLe64(file_.data());
  if (header_size > file_size - 8) {
    fail("header length " + std::to_string(header_size) + " exceeds the file size (" +
         std::to_string(file_size) + " bytes); truncated or not a safetensors file");
  }
  if (header_size > kMaxHeaderBytes) {
    fail("header length " + std::to_string(header_size) + " exceeds the 100 MB limit");
  }
  if (header_size < 2) fail("header too short (" + std::to_string(header_size) + " bytes)");

  const Json header = parseHeader(reinterpret_cast<const char*>(file_.data() + 8), header_size);
  const uint64_t data_size = file_size - 8 - header_size;
  const uint8_t* data_section = file_.data() + 8 + header_size;

  struct Placed {
    uint64_t begin, end;
    size_t header_index;
  };
  std::vector<Placed> placed;
  std::vector<TensorView> views;
  for (const auto& [key, value] : header.items()) {
    if (key == "__metadata__") {
      readMetadata(value);
      continue;
    }
    // What the writer refuses, so that `ffloc convert` blames the input, not its output.
    if (key.empty()) fail("a tensor has the empty name ''");
    std::pair<uint64_t, uint64_t> range;
    views.push_back(readTensor(key, value, data_size, data_section, &range));
    placed.push_back({range.first, range.second, views.size() - 1});
  }

  // File order is data order; ties (empty tensors) go by name.
  std::stable_sort(placed.begin(), placed.end(),
                   [](const Placed& a, const Placed& b) { return a.begin < b.begin; });
  uint64_t previous_end = 0;
  const std::string* previous_name = nullptr;
  for (const Placed& item : placed) {
    const std::string& name = views[item.header_index].name;
    if (item.begin == item.end) continue;
    if (item.begin < previous_end) {
      failTensor(name, "data_offsets [" + std::to_string(item.begin) + ", " +
                           std::to_string(item.end) + ") overlap tensor '" + *previous_name + "'");
    }
    previous_end = item.end;
    previous_name = &name;
  }
  // As the reference reader refuses them: two map files joined by `cat` opened as the first, and
  // a map extended in place was served as if whole.
  if (previous_end < data_size) {
    fail(std::to_string(data_size - previous_end) + " bytes follow the last tensor's data (which ends at byte " +
         std::to_string(8 + header_size + previous_end) + " of " + std::to_string(file_size) +
         "): the file was appended to or joined with another");
  }
  for (const Placed& item : placed) {
    TensorView& view = views[item.header_index];
    names_.push_back(view.name);
    tensors_.emplace(view.name, std::move(view));
  }
}

Json SafetensorsArchive::parseHeader(const char* text, size_t size) const {
  // nlohmann keeps the last of duplicated keys silently; a duplicated tensor name would hide a
  // tensor, so it is caught while parsing.
  std::set<std::string> seen;
  std::string duplicate;
  // Per open container: its values (a list) or keys (an object) so far, and how many it may hold.
  struct Open {
    int count = 0;
    int limit = 0;  // 0: unbounded (the top object, the metadata)
    bool list = false;
  };
  std::vector<Open> open;
  std::string top_key;
  const Json::parser_callback_t catch_duplicates = [&](int depth, Json::parse_event_t event,
                                                       Json& parsed) {
    if (depth > kMaxHeaderDepth) {
      fail("header: JSON nested deeper than " + std::to_string(kMaxHeaderDepth) + " levels");
    }
    const bool adds_a_value = event == Json::parse_event_t::value || event == Json::parse_event_t::array_start ||
                              event == Json::parse_event_t::object_start;
    const bool counts = (adds_a_value && !open.empty() && open.back().list) ||
                        (event == Json::parse_event_t::key && !open.empty() && !open.back().list);
    if (counts && open.back().limit > 0 && ++open.back().count > open.back().limit) {
      fail(open.back().list ? "header: a list of more than " + std::to_string(kMaxHeaderListLength) +
                                  " values (shapes and data offsets hold a few)"
                            : "header: tensor '" + top_key + "' has more than " + std::to_string(kMaxTensorEntryKeys) +
                                  " fields (dtype, shape and data_offsets)");
    }
    if (event == Json::parse_event_t::array_start) open.push_back({0, kMaxHeaderListLength, true});
    if (event == Json::parse_event_t::object_start)
      open.push_back({0, open.empty() || top_key == "__metadata__" ? 0 : kMaxTensorEntryKeys, false});
    if ((event == Json::parse_event_t::array_end || event == Json::parse_event_t::object_end) && !open.empty())
      open.pop_back();
    if (event == Json::parse_event_t::key && depth == 1 && parsed.is_string()) {
      top_key = parsed.get<std::string>();
      if (!seen.insert(top_key).second && duplicate.empty()) duplicate = top_key;
    }
    return true;
  };
  Json header;
  try {
    header = Json::parse(text, text + size, catch_duplicates);
  } catch (const Json::exception& error) {
    fail(std::string("malformed JSON header: ") + error.what());
  }
  if (!duplicate.empty()) fail("header: duplicated key '" + duplicate + "'");
  if (!header.is_object()) fail("header: expected a JSON object");
  return header;
}

void SafetensorsArchive::readMetadata(const Json& value) {
  if (!value.is_object()) fail("__metadata__: expected an object of strings");
  for (const auto& [key, entry] : value.items()) {
    if (!entry.is_string()) fail("__metadata__: value of '" + key + "' is not a string");
    metadata_[key] = entry.get<std::string>();
  }
}

TensorView SafetensorsArchive::readTensor(const std::string& name, const Json& entry,
                                          uint64_t data_size, const uint8_t* data_section,
                                          std::pair<uint64_t, uint64_t>* range) const {
  if (!entry.is_object()) failTensor(name, "expected an object with dtype, shape, data_offsets");
  TensorView view;
  view.name = name;

  const auto dtype_field = entry.find("dtype");
  if (dtype_field == entry.end() || !dtype_field->is_string()) {
    failTensor(name, "missing or non-string 'dtype'");
  }
  const std::optional<DType> dtype = dtypeFromString(dtype_field->get<std::string>());
  if (!dtype) {
    failTensor(name, "unknown dtype '" + dtype_field->get<std::string>() +
                         "' (supported: F32, F16, BF16, F64, I64, I32, I16, I8, U8, BOOL)");
  }
  view.dtype = *dtype;

  const auto shape_field = entry.find("shape");
  if (shape_field == entry.end() || !shape_field->is_array()) {
    failTensor(name, "missing or non-array 'shape'");
  }
  // Every entry is checked before the field is printed, so messages stay short.
  for (const Json& dim : *shape_field) {
    if (!dim.is_number_unsigned()) {
      failTensor(name, "shape entry " + (dim.is_number() ? dim.dump() : std::string(dim.type_name())) +
                           " is not a non-negative integer");
    }
  }
  uint64_t numel = 1;
  for (const Json& dim : *shape_field) {
    const uint64_t extent = dim.get<uint64_t>();
    if (extent > static_cast<uint64_t>(std::numeric_limits<int64_t>::max()) ||
        __builtin_mul_overflow(numel, extent, &numel)) {
      failTensor(name, "shape " + shape_field->dump() + " overflows the element count");
    }
    view.shape.push_back(static_cast<int64_t>(extent));
  }
  uint64_t nbytes = 0;
  if (__builtin_mul_overflow(numel, static_cast<uint64_t>(elementSize(view.dtype)), &nbytes)) {
    failTensor(name, "shape " + shape_field->dump() + " overflows the byte size");
  }

  const auto offsets_field = entry.find("data_offsets");
  if (offsets_field == entry.end() || !offsets_field->is_array() || offsets_field->size() != 2 ||
      !(*offsets_field)[0].is_number_unsigned() || !(*offsets_field)[1].is_number_unsigned()) {
    failTensor(name, "'data_offsets' must be two non-negative integers");
  }
  const uint64_t begin = (*offsets_field)[0].get<uint64_t>();
  const uint64_t end = (*offsets_field)[1].get<uint64_t>();
  if (end < begin) failTensor(name, "data_offsets " + offsets_field->dump() + " end before begin");
  if (end > data_size) {
    failTensor(name, "data_offsets " + offsets_field->dump() + " run past the data section (" +
                         std::to_string(data_size) + " bytes); file truncated?");
  }
  if (end - begin != nbytes) {
    failTensor(name, "data_offsets " + offsets_field->dump() + " span " +
                         std::to_string(end - begin) + " bytes but " + toString(view.dtype) +
                         " shape " + shape_field->dump() + " needs " + std::to_string(nbytes));
  }
  view.data = data_section + begin;
  view.nbytes = static_cast<size_t>(nbytes);
  *range = {begin, end};
  return view;
}

// Temporary files of `target` left by writers that were killed (Ctrl-C while a map was saved
// left one each time, up to the map's size, and no later run removed them): those named for a
// process that no longer runs.
void removeAbandonedTemporaries(const std::filesystem::path& directory, const std::filesystem::path& target) {
  const std::string prefix = "." + target.filename().string() + ".";
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(directory, error)) {
    const std::string name = entry.path().filename().string();
    if (name.size() <= prefix.size() + 4 || name.rfind(prefix, 0) != 0 || name.substr(name.size() - 4) != ".tmp")
      continue;
    // Exactly "<pid>.<counter>.tmp": ".m.ffmap.5.4242.0.tmp" is a temporary of "m.ffmap.5".
    const std::string rest = name.substr(prefix.size(), name.size() - prefix.size() - 4);
    const size_t dot = rest.find('.');
    const auto digits = [](const std::string& text) {
      return !text.empty() && text.find_first_not_of("0123456789") == std::string::npos;
    };
    if (dot == std::string::npos || dot > 9 || !digits(rest.substr(0, dot)) || !digits(rest.substr(dot + 1)))
      continue;
    const long pid = std::stol(rest.substr(0, dot));
    if (pid > 0 && ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH)
      std::filesystem::remove(entry.path(), error);
  }
}

// Creates a fresh file beside `target` (same directory, so rename() is atomic); the kernel
// applies the umask to the 0666 mode.
int createTemporaryBeside(const std::filesystem::path& target, std::filesystem::path* temporary) {
  static std::atomic<unsigned> counter{0};
  const std::filesystem::path directory =
      target.has_parent_path() ? target.parent_path() : std::filesystem::path(".");
  removeAbandonedTemporaries(directory, target);
  for (int attempt = 0; attempt < 100; ++attempt) {
    *temporary = directory / ("." + target.filename().string() + "." +
                              std::to_string(::getpid()) + "." + std::to_string(counter++) +
                              ".tmp");
    const int fd = ::open(temporary->c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd >= 0) return fd;
    if (errno != EEXIST) break;
  }
  throwInputError(target.string(), 0,
                  std::string("cannot create a temporary file beside it: ") + std::strerror(errno));
}

void writeAll(int fd, const uint8_t* bytes, size_t size, const std::filesystem::path& target) {
  while (size > 0) {
    const ssize_t written = ::write(fd, bytes, std::min<size_t>(size, 1u << 30));
    if (written < 0) {
      if (errno == EINTR) continue;
      throwInputError(target.string(), 0, std::string("write failed: ") + std::strerror(errno));
    }
    bytes += written;
    size -= static_cast<size_t>(written);
  }
}

}  // namespace

std::unique_ptr<TensorArchive> openSafetensors(const std::filesystem::path& path, FileMapping mapping) {
  return std::make_unique<SafetensorsArchive>(path, mapping);
}

void writeSafetensors(const std::filesystem::path& path, const std::vector<TensorView>& tensors,
                      const std::map<std::string, std::string>& metadata,
                      const WriteProgress& progress) {
  const std::string file = path.string();
  Json header = Json::object();
  if (!metadata.empty()) {
    Json meta = Json::object();
    for (const auto& [key, value] : metadata) meta[key] = value;
    header["__metadata__"] = meta;
  }
  uint64_t offset = 0;
  std::set<std::string> names;
  for (const TensorView& view : tensors) {
    if (view.name.empty() || view.name == "__metadata__") {
      throwInputError(file, 0, "tensor name '" + view.name + "' is not allowed");
    }
    if (!names.insert(view.name).second) {
      throwInputError(file, 0, "tensor '" + view.name + "': duplicated name");
    }
    uint64_t numel = 1;
    for (int64_t dim : view.shape) {
      if (dim < 0 || __builtin_mul_overflow(numel, static_cast<uint64_t>(dim), &numel)) {
        throwInputError(file, 0, "tensor '" + view.name + "': invalid shape " + view.shapeString());
      }
    }
    uint64_t nbytes = 0;
    if (__builtin_mul_overflow(numel, static_cast<uint64_t>(elementSize(view.dtype)), &nbytes) ||
        nbytes != view.nbytes || (view.nbytes > 0 && !view.data)) {
      throwInputError(file, 0, "tensor '" + view.name + "': " + std::to_string(view.nbytes) +
                                   " bytes do not match " + toString(view.dtype) + " shape " +
                                   view.shapeString());
    }
    header[view.name] = {{"dtype", toString(view.dtype)},
                         {"shape", view.shape},
                         {"data_offsets", {offset, offset + view.nbytes}}};
    offset += view.nbytes;
  }
  std::string text;
  try {
    text = header.dump();
  } catch (const Json::exception& error) {
    // A name read from the input that is not UTF-8 (a .pth's), not the output, is at fault.
    for (const TensorView& view : tensors)
      if (!isUtf8(view.name))
        throwInputError(file, 0, "tensor name '" + escapeControlCharacters(view.name) +
                                     "' is not UTF-8, which a safetensors header (JSON) cannot hold");
    throwInputError(file, 0, std::string("cannot encode the header: ") + error.what());
  }
  text.append((8 - text.size() % 8) % 8, ' ');
  uint8_t length[8];
  writeLe64(text.size(), length);

  // Written through a link, the link stays and what it names is replaced; a device or a FIFO
  // is refused: the rename replaced /dev/null itself with the file.
  const std::filesystem::path target = followSymlinks(path);
  std::error_code status_error;
  const std::filesystem::file_status status = std::filesystem::status(target, status_error);
  if (std::filesystem::exists(status) && !std::filesystem::is_regular_file(status))
    throwInputError(file, 0, "exists and is not a regular file (a folder, device, FIFO or socket), which the write "
                             "would replace; write to a file");
  std::filesystem::path temporary_path;
  const int fd = createTemporaryBeside(target, &temporary_path);
  TemporaryFile temporary(temporary_path);
  bool closed = false;
  try {
    writeAll(fd, length, sizeof(length), path);
    writeAll(fd, reinterpret_cast<const uint8_t*>(text.data()), text.size(), path);
    for (size_t i = 0; i < tensors.size(); ++i) {
      writeAll(fd, tensors[i].data, tensors[i].nbytes, path);
      if (progress) progress(i + 1);
    }
    if (::fsync(fd) != 0) {
      throwInputError(file, 0, std::string("fsync failed: ") + std::strerror(errno));
    }
    closed = true;
    if (::close(fd) != 0) {
      throwInputError(file, 0, std::string("close failed: ") + std::strerror(errno));
    }
  } catch (...) {
    if (!closed) ::close(fd);
    throw;
  }
  if (::rename(temporary.path().c_str(), target.c_str()) != 0)
    throwInputError(file, 0, std::string("cannot rename the temporary file into place: ") + std::strerror(errno));
  temporary.keep();
}

}  // namespace ffloc
