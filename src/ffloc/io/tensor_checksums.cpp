#include "ffloc/io/tensor_checksums.h"

#include <algorithm>
#include <optional>

#include "ffloc/core/error.h"
#include "ffloc/core/hash.h"
#include "ffloc/core/ordered_parallel.h"
#include "ffloc/io/json_fields.h"
#include "ffloc/io/mapped_file.h"

namespace ffloc {
namespace {

// The metadata entries but the checksums' own, in key order, each key and value preceded by its
// length so that no other set of entries hashes the same text.
std::string metadataChecksum(const std::map<std::string, std::string>& metadata) {
  uint64_t hash = fnv1a64(nullptr, 0);  // the offset basis
  auto add = [&](const std::string& text) {
    const std::string length = std::to_string(text.size()) + ":";
    hash = fnv1a64(reinterpret_cast<const uint8_t*>(length.data()), length.size(), hash);
    hash = fnv1a64(reinterpret_cast<const uint8_t*>(text.data()), text.size(), hash);
  };
  for (const auto& [key, value] : metadata) {
    if (key == kChecksumsMetadataKey) continue;
    add(key);
    add(value);
  }
  return hex64(hash);
}

std::vector<std::string> checksumsOf(const std::vector<ByteRange>& ranges) {
  std::vector<std::string> checksums;
  for (uint64_t hash : fnv1a64Each(ranges)) checksums.push_back(hex64(hash));
  return checksums;
}

// The tensors' recorded checksums once the metadata's own is verified; nullopt for a file
// without checksums.
std::optional<nlohmann::json> recordedTensorChecksums(const TensorArchive& archive) {
  const auto entry = archive.metadata().find(kChecksumsMetadataKey);
  if (entry == archive.metadata().end()) return std::nullopt;
  const std::string file = archive.path().string();
  const std::string source = file + ": metadata '" + kChecksumsMetadataKey + "'";
  nlohmann::json checksums = parseJson(entry->second, source);
  const JsonFields fields(checksums, source, "");
  if (fields.string("metadata") != metadataChecksum(archive.metadata()))
    throwInputError(file, 0, "metadata checksum mismatch (the file is corrupted)");
  if (!fields.get("tensors").is_object()) fields.fail("tensors", "expected an object of tensor name -> checksum");
  return std::move(checksums["tensors"]);
}

}  // namespace

// One range: the four-lane hash would hash three lanes of zeros beside it.
std::string tensorChecksum(const TensorView& view) { return hex64(fnv1a64(view.data, view.nbytes)); }

std::string mappedTensorChecksum(const TensorView& view) {
  constexpr size_t kStretch = size_t{4} << 20;
  uint64_t hash = fnv1a64(nullptr, 0);
  for (size_t offset = 0; offset < view.nbytes; offset += kStretch) {
    const size_t size = std::min(kStretch, view.nbytes - offset);
    hash = fnv1a64(view.data + offset, size, hash);
    releaseMappedPages(view.data + offset, size);
  }
  return hex64(hash);
}

void checkTensorChecksum(const std::string& name, const std::string& checksum, const nlohmann::json& recorded,
                         const std::string& file) {
  const auto expected = recorded.find(name);
  if (expected == recorded.end() || !expected->is_string())
    throwInputError(file, 0, "tensor '" + name + "': no checksum recorded");
  if (expected->get_ref<const std::string&>() != checksum)
    throwInputError(file, 0, "tensor '" + name + "': checksum mismatch (the file is corrupted)");
}

std::map<std::string, std::string> withChecksums(const std::vector<TensorView>& tensors,
                                                 std::map<std::string, std::string> metadata) {
  std::vector<ByteRange> ranges;
  for (const TensorView& view : tensors) ranges.push_back({view.data, view.nbytes});
  const std::vector<std::string> sums = checksumsOf(ranges);
  nlohmann::json checksums = nlohmann::json::object();
  for (size_t i = 0; i < tensors.size(); ++i) checksums[tensors[i].name] = sums[i];
  const nlohmann::json entry = {{"metadata", metadataChecksum(metadata)}, {"tensors", checksums}};
  metadata[kChecksumsMetadataKey] = entry.dump();
  return metadata;
}

void verifyMetadataChecksum(const TensorArchive& archive) { recordedTensorChecksums(archive); }

void requireEveryRecordedTensor(const TensorArchive& archive, const nlohmann::json& recorded, const std::string& file) {
  for (const auto& item : recorded.items()) {
    if (!archive.contains(item.key()))
      throwInputError(file, 0, "tensor '" + item.key() + "': checksum recorded, but the file has no such tensor");
  }
}

void verifyChecksums(const TensorArchive& archive, int workers) {
  const std::optional<nlohmann::json> recorded = recordedTensorChecksums(archive);
  if (!recorded) return;
  const std::string file = archive.path().string();
  const std::vector<std::string>& names = archive.names();
  // Batches of consecutive tensors, so that each thread hashes several at once.
  constexpr size_t kBatch = 16;
  forEachInOrder<std::vector<std::string>>(
      (names.size() + kBatch - 1) / kBatch, workers,
      [&](size_t batch) {
        std::vector<ByteRange> ranges;
        for (size_t i = batch * kBatch; i < std::min(names.size(), (batch + 1) * kBatch); ++i) {
          const TensorView& view = archive.at(names[i]);
          ranges.push_back({view.data, view.nbytes});
        }
        return checksumsOf(ranges);
      },
      [&](size_t batch, const std::vector<std::string>& checksums) {
        for (size_t j = 0; j < checksums.size(); ++j)
          checkTensorChecksum(names[batch * kBatch + j], checksums[j], *recorded, file);
      });
  requireEveryRecordedTensor(archive, *recorded, file);
}

}  // namespace ffloc
