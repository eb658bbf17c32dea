#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "ffloc/core/error.h"
#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"
#include "ffloc/geometry/preprocess.h"
#include "ffloc/io/tensor_archive.h"

namespace ffloc {

// A map image's tokens, fp16 bits, row-major (token, channel). Held in memory while a map is
// built; a view into the map file's snapshot once a map is read (mapped_file.h): reading a map
// makes no per-image copies (a 150-image map of the large configuration held 236 MB of them), a
// query pages in only the K images it selects, and a map file replaced on disk, or written over
// in place, leaves the view intact.
class StoredTokens {
 public:
  StoredTokens() = default;
  explicit StoredTokens(std::vector<uint16_t> values) : owned_(std::move(values)) {}
  // `data` must stay valid as long as `keep_alive` lives.
  StoredTokens(std::shared_ptr<const void> keep_alive, const uint16_t* data, size_t size)
      : keep_alive_(std::move(keep_alive)), view_(data), view_size_(size) {}

  const uint16_t* data() const { return view_ ? view_ : owned_.data(); }
  size_t size() const { return view_ ? view_size_ : owned_.size(); }
  bool mapped() const { return view_ != nullptr; }
  bool operator==(const StoredTokens& other) const;  // the same values, however held

 private:
  std::vector<uint16_t> owned_;
  std::shared_ptr<const void> keep_alive_;
  const uint16_t* view_ = nullptr;
  size_t view_size_ = 0;
};

// One mapping image as the map stores it: encoded once at mapping time, so a query never
// re-encodes the mapping images (the paper re-encodes them for every query).
struct MapImage {
  std::string name;
  Pose camera_to_world;              // the frame's pose, scene units
  Intrinsics intrinsics;             // of the preprocessed image the tokens were computed from
  PreprocessGeometry geometry;       // original image -> preprocessed image
  int grid_rows = 0, grid_cols = 0;  // token grid; tokens = grid_rows * grid_cols
  StoredTokens tokens;
  std::vector<float> descriptor;     // global descriptor for retrieval
  std::vector<float> vlad_descriptor;  // the classical one, when the map has a VLAD vocabulary
  // Each token's 3D point (world frame, scene units), row-major (token, xyz), NaN where the token
  // has none; empty when the mapping frame had no depth. Models with a point encoder or a
  // matching head use them (fastforward_config.h).
  std::vector<float> token_points;

  size_t tokenCount() const { return static_cast<size_t>(grid_rows) * grid_cols; }
};

// A map: one versioned safetensors file (tokens as F16 tensors, descriptors as one F32 matrix)
// whose JSON metadata holds the poses, intrinsics, preprocessing geometry and image names, a
// checksum of every tensor, and the identity of the model that made the tokens.
struct MapFile {
  // 2: the model identity covers the architecture (model_loader.h); a version 1 map's does not,
  // so no model of this build matches it.
  static constexpr int kVersion = 2;

  std::string model_id;  // identity of the weights that produced the tokens
  int token_dim = 0;
  bool metric = true;
  // Optional (ffloc map --vlad): the classical VLAD vocabulary, words x 128 row-major, so that
  // FastForward can select its K images by classical retrieval. Empty: none.
  std::vector<float> vlad_centres;
  // The vocabulary of FastForward's default retrieval (token VLAD, pipeline/token_vlad.h), words x
  // token_dim row-major, learnt from the tokens when the map is built and kept by an append.
  // Empty in maps written before 5 Dec 2026: the first query that ranks with it learns it then.
  std::vector<float> token_vocabulary;
  std::vector<MapImage> images;
};

// What every map file says of itself, whatever its method: the method that built it and the
// version of that method's map format. InputError naming the file when it is not an ffloc map.
struct MapHeader {
  std::string method;  // "fastforward" or "classical"
  int version = 0;
};
MapHeader readMapHeader(const std::filesystem::path& path);
// Whether `path` holds a map (its header reads): an output that is no map must not replace one.
bool isMapFile(const std::filesystem::path& path);
// A map in memory knows no file, so the library's errors about one start "map: "; read from or
// written to `path`, the error names the file instead. Other errors are returned as they are.
InputError namingMapFile(const InputError& error, const std::filesystem::path& path);
// The same from a container already open: its JSON description (checked against its checksum
// where the map has one; maps written before it was added have none), then the header in it.
nlohmann::json readMapMetadata(const TensorArchive& archive, const std::string& file);
MapHeader mapHeader(const nlohmann::json& metadata, const std::string& file);

// The container's metadata key that holds a map's JSON description, and the key beside it that
// holds the description's checksum (FNV-1a 64, hex): the tensors' checksums are in the
// description, and this one covers the description itself (poses, intrinsics, names).
inline constexpr const char* kMapMetadataKey = "ffloc_map";
inline constexpr const char* kMapMetadataChecksumKey = "ffloc_map_checksum";

// The container metadata that stores `description`: the text and its checksum. InputError
// naming `file` when the description cannot be encoded (a string that is not UTF-8).
std::map<std::string, std::string> mapMetadataEntries(const nlohmann::json& description, const std::string& file);

// Atomic: written to a temporary file beside `path`, then renamed, so an interrupted write
// never damages an existing map. InputError naming the image for inconsistent sizes.
void writeMapFile(const MapFile& map, const std::filesystem::path& path);

// Validates the container, the version, every checksum and every size. When expected_model_id is
// non-empty and differs from the map's, InputError says which model built the map. The tokens
// are views into a snapshot of the file taken here (StoredTokens), so the map holds memory of the
// file's size for as long as it lives; every tensor's checksum is verified here, streaming over
// the snapshot and releasing each stretch once hashed, so the check leaves no token resident.
MapFile readMapFile(const std::filesystem::path& path, const std::string& expected_model_id = "");

}  // namespace ffloc
