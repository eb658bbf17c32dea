#pragma once

#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "ffloc/io/tensor_archive.h"

namespace ffloc {

// The checksum of a tensor that maps (map_file.h, classical_map.h) and training checkpoints
// record: FNV-1a 64 (core/hash.h) of its bytes, 16 hex digits. Without them a damaged file (a
// flipped byte, a file truncated and padded, a disk error) loads as other values, silently.
std::string tensorChecksum(const TensorView& view);
// The same for a view into a read-only file mapping that the caller keeps mapped (a map's
// tokens): read a stretch at a time, each stretch released from the process's memory once hashed
// (mapped_file.h), so that checking a whole map leaves none of it resident.
std::string mappedTensorChecksum(const TensorView& view);

// InputError naming the file and the tensor unless `recorded` (a JSON object of tensor name ->
// checksum) holds `checksum` for tensor `name`: "tensor 'w': no checksum recorded", "tensor 'w':
// checksum mismatch (the file is corrupted)".
void checkTensorChecksum(const std::string& name, const std::string& checksum, const nlohmann::json& recorded,
                         const std::string& file);

// InputError naming the file for the first tensor `recorded` (name -> checksum) names that the
// archive lacks: a byte flipped in a tensor's name dropped it from a map unnoticed, and an append
// then dropped its checksum too.
void requireEveryRecordedTensor(const TensorArchive& archive, const nlohmann::json& recorded, const std::string& file);

// A safetensors file that carries its own checksums (what training writes: model and optimizer
// state) holds them in this metadata entry: {"metadata": <FNV-1a 64 of the other metadata
// entries>, "tensors": {<name>: <tensorChecksum>}}. The metadata's checksum matters as much as the
// tensors': a model's head count or input size lives there, invisible in any tensor's shape.
inline constexpr const char* kChecksumsMetadataKey = "ffloc_checksums";

// `metadata` with the checksums of `tensors` and of itself added, for writeSafetensors.
std::map<std::string, std::string> withChecksums(const std::vector<TensorView>& tensors,
                                                 std::map<std::string, std::string> metadata);

// For a file that carries checksums: InputError naming the file unless its metadata still hash
// to theirs. Files without (written before checksums, or elsewhere: DUSt3R checkpoints, the
// shipped models) pass unchecked.
void verifyMetadataChecksum(const TensorArchive& archive);
// The same, then every tensor against its checksum, hashed on `workers` threads: checkTensorChecksum's
// errors for the first tensor in file order that fails, or "tensor 'w': checksum recorded, but the
// file has no such tensor".
void verifyChecksums(const TensorArchive& archive, int workers);

}  // namespace ffloc
