#include "ffloc/io/map_file.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <set>
#include <nlohmann/json.hpp>

#include "ffloc/core/error.h"
#include "ffloc/core/hash.h"
#include "ffloc/io/input_file.h"
#include "ffloc/io/json_fields.h"
#include "ffloc/io/tensor_archive.h"
#include "ffloc/io/tensor_checksums.h"

namespace ffloc {
namespace {

constexpr const char* kMetadataKey = kMapMetadataKey;
constexpr const char* kMethod = "fastforward";
constexpr const char* kDescriptorsTensor = "descriptors";
constexpr const char* kVladVocabularyTensor = "vlad_vocabulary";
constexpr const char* kVladDescriptorsTensor = "vlad_descriptors";
constexpr const char* kTokenVocabularyTensor = "token_vocabulary";

std::string tokensTensorName(size_t index) { return "tokens." + std::to_string(index); }
std::string pointsTensorName(size_t index) { return "points." + std::to_string(index); }

// Sides of an image, in pixels, beyond any camera; and token widths beyond any model.
constexpr int64_t kMaxImageSide = 1 << 20;
constexpr int64_t kMaxTokenDim = 1 << 16;
// Words of a token vocabulary beyond any this project writes (128): each map image's descriptor
// holds words x token width floats, and an outside probe's 20 000 words took a query to 1.5 GB.
constexpr int64_t kMaxTokenVocabularyWords = 1024;

// Exactly as written, once checked like every dataset reader's poses.
Pose readPose(const JsonFields& image) {
  const Eigen::Matrix4d T = image.matrix4("camera_to_world");
  if (!T.allFinite()) image.fail("camera_to_world", "not finite");
  if ((T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-6)
    image.fail("camera_to_world", "last row is not (0 0 0 1)");
  Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  if (!projectToRotation(R)) image.fail("camera_to_world", "rotation is not orthonormal");
  return Pose::fromMatrix(T);
}

Intrinsics readIntrinsics(const JsonFields& k) {
  Intrinsics intrinsics;
  intrinsics.fx = k.finiteNumber("fx");
  intrinsics.fy = k.finiteNumber("fy");
  intrinsics.cx = k.finiteNumber("cx");
  intrinsics.cy = k.finiteNumber("cy");
  if (!(intrinsics.fx > 0)) k.fail("fx", "must be positive");
  if (!(intrinsics.fy > 0)) k.fail("fy", "must be positive");
  intrinsics.width = static_cast<int>(k.integer("width", 1, kMaxImageSide));
  intrinsics.height = static_cast<int>(k.integer("height", 1, kMaxImageSide));
  return intrinsics;
}

PreprocessGeometry readGeometry(const JsonFields& g) {
  PreprocessGeometry geometry;
  auto side = [&](const char* key) { return static_cast<int>(g.integer(key, 1, kMaxImageSide)); };
  geometry.original_width = side("original_width");
  geometry.original_height = side("original_height");
  geometry.resized_width = side("resized_width");
  geometry.resized_height = side("resized_height");
  geometry.width = side("width");
  geometry.height = side("height");
  geometry.crop_x = static_cast<int>(g.integer("crop_x", 0, geometry.resized_width - geometry.width));
  geometry.crop_y = static_cast<int>(g.integer("crop_y", 0, geometry.resized_height - geometry.height));
  return geometry;
}

bool allFinite(const TensorView& view) {
  for (size_t i = 0; i < view.nbytes / sizeof(float); ++i) {
    float value;
    std::memcpy(&value, view.data + i * sizeof(float), sizeof(float));
    if (!std::isfinite(value)) return false;
  }
  return true;
}

// Appends a rows x cols tensor over `data` (which must outlive the write) and its checksum.
void addTensor(const std::string& name, DType dtype, const void* data, size_t rows, size_t cols, size_t element_bytes,
               std::vector<TensorView>& tensors, nlohmann::json& checksums) {
  TensorView view;
  view.name = name;
  view.dtype = dtype;
  view.shape = {static_cast<int64_t>(rows), static_cast<int64_t>(cols)};
  view.data = static_cast<const uint8_t*>(data);
  view.nbytes = rows * cols * element_bytes;
  checksums[view.name] = tensorChecksum(view);
  tensors.push_back(view);
}

void addF32Tensor(const std::string& name, const std::vector<float>& values, size_t rows, size_t cols,
                  std::vector<TensorView>& tensors, nlohmann::json& checksums) {
  addTensor(name, DType::kF32, values.data(), rows, cols, sizeof(float), tensors, checksums);
}

}  // namespace

bool StoredTokens::operator==(const StoredTokens& other) const {
  return size() == other.size() && std::equal(data(), data() + size(), other.data());
}

void writeMapFile(const MapFile& map, const std::filesystem::path& path) {
  if (map.token_dim <= 0) throw InputError(path.string() + ": map: token dimension must be positive");
  std::vector<TensorView> tensors;
  nlohmann::json images = nlohmann::json::array();
  nlohmann::json checksums = nlohmann::json::object();
  std::vector<float> descriptors;
  const size_t descriptor_dim = map.images.empty() ? 0 : map.images.front().descriptor.size();

  for (size_t i = 0; i < map.images.size(); ++i) {
    const MapImage& image = map.images[i];
    const std::string where = path.string() + ": map image '" + image.name + "'";
    if (image.tokens.size() != image.tokenCount() * static_cast<size_t>(map.token_dim))
      throw InputError(where + ": " + std::to_string(image.tokens.size()) + " token values for a " +
                       std::to_string(image.grid_rows) + "x" + std::to_string(image.grid_cols) + " grid of dimension " +
                       std::to_string(map.token_dim));
    if (image.descriptor.size() != descriptor_dim)
      throw InputError(where + ": descriptor of length " + std::to_string(image.descriptor.size()) + ", expected " +
                       std::to_string(descriptor_dim));
    addTensor(tokensTensorName(i), DType::kF16, image.tokens.data(), image.tokenCount(), map.token_dim, sizeof(uint16_t),
              tensors, checksums);
    descriptors.insert(descriptors.end(), image.descriptor.begin(), image.descriptor.end());
    if (!image.token_points.empty()) {
      if (image.token_points.size() != 3 * image.tokenCount())
        throw InputError(where + ": " + std::to_string(image.token_points.size()) + " point values for " +
                         std::to_string(image.tokenCount()) + " tokens");
      addF32Tensor(pointsTensorName(i), image.token_points, image.tokenCount(), 3, tensors, checksums);
    }

    const Intrinsics& k = image.intrinsics;
    const PreprocessGeometry& g = image.geometry;
    images.push_back({{"name", image.name},
                      {"camera_to_world", matrix4Json(image.camera_to_world.matrix())},
                      {"intrinsics", {{"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy},
                                      {"width", k.width}, {"height", k.height}}},
                      {"preprocess", {{"original_width", g.original_width}, {"original_height", g.original_height},
                                      {"resized_width", g.resized_width}, {"resized_height", g.resized_height},
                                      {"crop_x", g.crop_x}, {"crop_y", g.crop_y},
                                      {"width", g.width}, {"height", g.height}}},
                      {"grid", {image.grid_rows, image.grid_cols}}});
  }
  std::vector<float> vlad_descriptors;
  const size_t vlad_dim = map.vlad_centres.size();
  if (vlad_dim % 128 != 0) throw InputError(path.string() + ": map: VLAD vocabulary is not words x 128");
  for (const MapImage& image : map.images) {
    if (image.vlad_descriptor.size() != vlad_dim)
      throw InputError(path.string() + ": map image '" + image.name + "': VLAD descriptor of length " +
                       std::to_string(image.vlad_descriptor.size()) + ", expected " + std::to_string(vlad_dim));
    vlad_descriptors.insert(vlad_descriptors.end(), image.vlad_descriptor.begin(), image.vlad_descriptor.end());
  }
  if (vlad_dim > 0) {
    addF32Tensor(kVladVocabularyTensor, map.vlad_centres, vlad_dim / 128, 128, tensors, checksums);
    addF32Tensor(kVladDescriptorsTensor, vlad_descriptors, map.images.size(), vlad_dim, tensors, checksums);
  }
  if (!map.token_vocabulary.empty()) {
    if (map.token_vocabulary.size() % map.token_dim != 0)
      throw InputError(path.string() + ": map: token vocabulary of " + std::to_string(map.token_vocabulary.size()) +
                       " values is not words x " + std::to_string(map.token_dim));
    addF32Tensor(kTokenVocabularyTensor, map.token_vocabulary, map.token_vocabulary.size() / map.token_dim,
                 map.token_dim, tensors, checksums);
  }
  addF32Tensor(kDescriptorsTensor, descriptors, map.images.size(), descriptor_dim, tensors, checksums);

  const nlohmann::json metadata = {{"method", kMethod}, {"version", MapFile::kVersion}, {"model_id", map.model_id},
                                   {"token_dim", map.token_dim},   {"metric", map.metric},
                                   {"images", images},             {"checksums", checksums}};
  writeSafetensors(path, tensors, mapMetadataEntries(metadata, path.string()));
}

std::map<std::string, std::string> mapMetadataEntries(const nlohmann::json& description, const std::string& file) {
  std::string text;
  try {
    text = description.dump();
  } catch (const nlohmann::json::exception& e) {
    throwInputError(file, 0, std::string("cannot encode the map metadata (an image name that is not UTF-8?): ") +
                                 e.what());
  }
  return {{kMetadataKey, text}, {kMapMetadataChecksumKey, hex64(fnv1a64(text))}};
}

nlohmann::json readMapMetadata(const TensorArchive& archive, const std::string& file) {
  const auto entry = archive.metadata().find(kMetadataKey);
  if (entry == archive.metadata().end())
    throwInputError(file, 0, "not an ffloc map (no '" + std::string(kMetadataKey) + "' metadata)");
  const auto checksum = archive.metadata().find(kMapMetadataChecksumKey);
  if (checksum != archive.metadata().end() && checksum->second != hex64(fnv1a64(entry->second)))
    throwInputError(file, 0, "map metadata checksum mismatch (the file is corrupted)");
  return parseJson(entry->second, file + ": map metadata");
}

MapHeader mapHeader(const nlohmann::json& metadata, const std::string& file) {
  MapHeader header;
  // Maps written before there was more than one method say nothing of it.
  if (!metadata.is_object()) throwInputError(file, 0, "map metadata is not a JSON object");
  const JsonFields fields(metadata, file, "");
  header.method = fields.has("method") ? fields.string("method") : kMethod;
  const nlohmann::json& version = metadata.contains("version") ? metadata["version"] : nlohmann::json();
  if (!version.is_number_integer() || version.get<int64_t>() < 0 || version.get<int64_t>() > 1000000)
    throwInputError(file, 0, "map field 'version' must be a small non-negative integer");
  header.version = static_cast<int>(version.get<int64_t>());
  return header;
}

MapHeader readMapHeader(const std::filesystem::path& path) {
  requireRegularFile(path, "map file");  // a mistyped path is that, not a damaged map
  std::shared_ptr<const TensorArchive> archive;
  try {
    archive = openSafetensors(path);
  } catch (const InputError& error) {
    // A manifest given as the map was refused for a "header length 7308604848694364795", which
    // told the user nothing about what they had given.
    throwInputError(path.string(), 0,
                    "not an ffloc map, or a damaged one: " + withoutFileName(error.what(), path.string()));
  }
  return mapHeader(readMapMetadata(*archive, path.string()), path.string());
}

bool isMapFile(const std::filesystem::path& path) {
  try {
    readMapHeader(path);
    return true;
  } catch (const InputError&) {
    return false;
  }
}

InputError namingMapFile(const InputError& error, const std::filesystem::path& path) {
  const std::string what = error.what();
  const std::string reason = withoutFileName(what, "map");
  return reason.size() == what.size() ? error : InputError(path.string() + ": " + reason);
}

MapFile readMapFile(const std::filesystem::path& path, const std::string& expected_model_id) {
  // Shared: each image's tokens keep the mapping alive. A snapshot: a map stays open in a server
  // or a Python session while the file may be written over in place, and the file as mapped then
  // changed under its tokens or, cut short, ended the process (SIGBUS) at the next query.
  const std::shared_ptr<const TensorArchive> archive = openSafetensors(path, FileMapping::kSnapshot);
  const std::string file = path.string();
  const nlohmann::json metadata = readMapMetadata(*archive, file);
  const MapHeader header = mapHeader(metadata, file);
  if (header.method != kMethod)
    throwInputError(file, 0, "map was built with the " + header.method +
                                 " method, not fastforward (localize it with the method it was built with)");
  const int version = header.version;
  if (version == 1)
    throwInputError(file, 0, "map version 1 identifies its model by the weights alone, and this build by the weights "
                             "and the architecture: rebuild the map with ffloc map");
  if (version != MapFile::kVersion)
    throwInputError(file, 0, "map version " + std::to_string(version) + " is not supported (this build reads version " +
                                 std::to_string(MapFile::kVersion) + ")");
  MapFile map;
  const JsonFields top(metadata, file, "");
  map.model_id = top.string("model_id");
  map.token_dim = static_cast<int>(top.integer("token_dim", 1, kMaxTokenDim));
  map.metric = top.boolean("metric");
  if (!expected_model_id.empty() && map.model_id != expected_model_id)
    throwInputError(file, 0, "map was built with model '" + map.model_id + "', but the loaded model is '" +
                                 expected_model_id + "': load the model the map was built with, or rebuild the map with this one");

  const nlohmann::json& checksums = top.get("checksums");
  if (!checksums.is_object()) top.fail("checksums", "expected an object of tensor name -> checksum");
  requireEveryRecordedTensor(*archive, checksums, file);
  auto verified = [&](const std::string& name) -> const TensorView& {
    const TensorView& view = archive->at(name);
    checkTensorChecksum(name, mappedTensorChecksum(view), checksums, file);
    return view;
  };

  const nlohmann::json& images = top.get("images");
  if (!images.is_array()) top.fail("images", "expected a list");
  const TensorView& descriptors = verified(kDescriptorsTensor);
  if (descriptors.dtype != DType::kF32 || descriptors.shape.size() != 2 ||
      descriptors.shape[0] != static_cast<int64_t>(images.size()))
    throwInputError(file, 0, "tensor 'descriptors' has shape " + descriptors.shapeString() + ", expected (" +
                                 std::to_string(images.size()) + ", D) F32");
  if (!allFinite(descriptors)) throwInputError(file, 0, "tensor 'descriptors' holds NaN or infinite values");
  const size_t descriptor_dim = static_cast<size_t>(descriptors.shape[1]);
  const float* vlad = nullptr;
  size_t vlad_dim = 0;
  if (archive->contains(kVladVocabularyTensor)) {
    const TensorView& centres = verified(kVladVocabularyTensor);
    if (centres.dtype != DType::kF32 || centres.shape.size() != 2 || centres.shape[1] != 128 || centres.shape[0] < 1)
      throwInputError(file, 0, "tensor 'vlad_vocabulary' has shape " + centres.shapeString() + " " +
                                   toString(centres.dtype) + ", expected (words, 128) F32");
    if (!allFinite(centres)) throwInputError(file, 0, "tensor 'vlad_vocabulary' holds NaN or infinite values");
    map.vlad_centres.resize(centres.nbytes / sizeof(float));
    std::memcpy(map.vlad_centres.data(), centres.data, centres.nbytes);
    vlad_dim = map.vlad_centres.size();
    const TensorView& per_image = verified(kVladDescriptorsTensor);
    if (per_image.dtype != DType::kF32 ||
        per_image.shape != std::vector<int64_t>{static_cast<int64_t>(images.size()), static_cast<int64_t>(vlad_dim)})
      throwInputError(file, 0, "tensor 'vlad_descriptors' has shape " + per_image.shapeString() + ", expected (" +
                                   std::to_string(images.size()) + ", " + std::to_string(vlad_dim) + ") F32");
    if (!allFinite(per_image)) throwInputError(file, 0, "tensor 'vlad_descriptors' holds NaN or infinite values");
    vlad = reinterpret_cast<const float*>(per_image.data);
  }

  if (archive->contains(kTokenVocabularyTensor)) {
    const TensorView& words = verified(kTokenVocabularyTensor);
    if (words.dtype != DType::kF32 || words.shape.size() != 2 || words.shape[0] < 1 ||
        words.shape[0] > kMaxTokenVocabularyWords || words.shape[1] != map.token_dim)
      throwInputError(file, 0, "tensor 'token_vocabulary' has shape " + words.shapeString() + " " + toString(words.dtype) +
                                   ", expected (words, " + std::to_string(map.token_dim) + ") F32 with 1 to " +
                                   std::to_string(kMaxTokenVocabularyWords) + " words");
    if (!allFinite(words)) throwInputError(file, 0, "tensor 'token_vocabulary' holds NaN or infinite values");
    map.token_vocabulary.resize(words.nbytes / sizeof(float));
    std::memcpy(map.token_vocabulary.data(), words.data, words.nbytes);
  }

  std::set<std::string> names;
  for (size_t i = 0; i < images.size(); ++i) {
    const JsonFields entry(images[i], file, "images[" + std::to_string(i) + "]");
    MapImage image;
    image.name = entry.string("name");
    if (!names.insert(image.name).second) entry.fail("name", "duplicate image name '" + image.name + "'");
    image.camera_to_world = readPose(entry);
    image.intrinsics = readIntrinsics(JsonFields(entry.get("intrinsics"), file, entry.field("intrinsics")));
    const JsonFields preprocess(entry.get("preprocess"), file, entry.field("preprocess"));
    image.geometry = readGeometry(preprocess);
    if (image.intrinsics.width != image.geometry.width || image.intrinsics.height != image.geometry.height)
      preprocess.fail("", "makes " + std::to_string(image.geometry.width) + "x" + std::to_string(image.geometry.height) +
                              " images, but the intrinsics are of a " + std::to_string(image.intrinsics.width) + "x" +
                              std::to_string(image.intrinsics.height) + " image");
    const std::vector<double> grid = entry.numbers("grid");
    if (grid.size() != 2 || !(grid[0] >= 1 && grid[0] <= kMaxImageSide && grid[0] == std::floor(grid[0])) ||
        !(grid[1] >= 1 && grid[1] <= kMaxImageSide && grid[1] == std::floor(grid[1])))
      entry.fail("grid", "expected two positive token counts (rows, columns)");
    image.grid_rows = static_cast<int>(grid[0]);
    image.grid_cols = static_cast<int>(grid[1]);

    const TensorView& tokens = verified(tokensTensorName(i));
    const std::vector<int64_t> expected_shape = {static_cast<int64_t>(image.tokenCount()), map.token_dim};
    if (tokens.dtype != DType::kF16 || tokens.shape != expected_shape)
      throwInputError(file, 0, "tensor '" + tokens.name + "' of image '" + image.name + "' has shape " +
                                   tokens.shapeString() + " " + toString(tokens.dtype) + ", expected (" +
                                   std::to_string(expected_shape[0]) + ", " + std::to_string(expected_shape[1]) + ") F16");
    const size_t values = tokens.nbytes / sizeof(uint16_t);
    if (reinterpret_cast<uintptr_t>(tokens.data) % alignof(uint16_t) == 0) {
      image.tokens = StoredTokens(archive, reinterpret_cast<const uint16_t*>(tokens.data), values);
    } else {
      // Our writer aligns every tensor; a file from elsewhere may not, and is copied.
      std::vector<uint16_t> copy(values);
      std::memcpy(copy.data(), tokens.data, tokens.nbytes);
      image.tokens = StoredTokens(std::move(copy));
    }
    image.descriptor.resize(descriptor_dim);
    std::memcpy(image.descriptor.data(), descriptors.data + i * descriptor_dim * sizeof(float),
                descriptor_dim * sizeof(float));
    if (vlad) image.vlad_descriptor.assign(vlad + i * vlad_dim, vlad + (i + 1) * vlad_dim);
    if (archive->contains(pointsTensorName(i))) {
      const TensorView& points = verified(pointsTensorName(i));
      if (points.dtype != DType::kF32 || points.shape != std::vector<int64_t>{static_cast<int64_t>(image.tokenCount()), 3})
        throwInputError(file, 0, "tensor '" + points.name + "' of image '" + image.name + "' has shape " +
                                     points.shapeString() + " " + toString(points.dtype) + ", expected (" +
                                     std::to_string(image.tokenCount()) + ", 3) F32");
      image.token_points.resize(3 * image.tokenCount());
      std::memcpy(image.token_points.data(), points.data, points.nbytes);
      // NaN marks a token without a point; an infinite coordinate is damage.
      for (float value : image.token_points) {
        if (std::isinf(value)) throwInputError(file, 0, "tensor '" + points.name + "' holds infinite values");
      }
    }
    map.images.push_back(std::move(image));
  }
  return map;
}

}  // namespace ffloc
