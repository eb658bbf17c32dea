#include "ffloc/classical/classical_map.h"

#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>
#include <set>

#include "ffloc/core/error.h"
#include "ffloc/core/hash.h"
#include "ffloc/io/json_fields.h"
#include "ffloc/io/map_file.h"
#include "ffloc/io/tensor_archive.h"
#include "ffloc/io/tensor_checksums.h"

namespace ffloc {
namespace {

constexpr const char* kMethod = "classical";
constexpr const char* kBodyKey = "ffloc_map_body";
constexpr int kPointColumns = 4;  // x, y, z relative to the origin, views

std::string tensorName(const char* kind, size_t image) { return std::string(kind) + "." + std::to_string(image); }

template <typename T>
TensorView viewOf(const std::string& name, DType dtype, std::vector<int64_t> shape, const std::vector<T>& values) {
  TensorView view;
  view.name = name;
  view.dtype = dtype;
  view.shape = std::move(shape);
  view.data = reinterpret_cast<const uint8_t*>(values.data());
  view.nbytes = values.size() * sizeof(T);
  return view;
}

// The map's poses are written from rigid transforms, so anything but a rotation (to rounding)
// and a 0 0 0 1 row is a damaged file.
Pose rigidPose(const JsonFields& fields, const std::string& key) {
  const Eigen::Matrix4d T = fields.matrix4(key);
  if (!T.allFinite()) fields.fail(key, "holds a value that is not a finite number");
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  if (orthogonalityError(R) > kRigidRotationTolerance || R.determinant() < 0 ||
      (T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9)
    fields.fail(key, "is not a rigid transform (rotation not orthonormal)");
  return Pose::fromMatrix(T);
}

}  // namespace

size_t ClassicalMapImage::pointCount() const {
  size_t count = 0;
  for (uint8_t views : point_views) count += views > 0;
  return count;
}

void writeClassicalMap(const ClassicalMap& map, const std::filesystem::path& path) {
  const std::string file = path.string();
  if (map.vocabulary.empty()) throwInputError(file, 0, "classical map: no vocabulary (no image had features)");
  const size_t descriptor_size = map.vocabulary.descriptorSize();

  // Points are stored as float relative to the centre of the cameras, so that scenes far from
  // their world origin (UTM coordinates) keep millimetres.
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  for (const ClassicalMapImage& image : map.images) origin += image.camera_to_world.t;
  if (!map.images.empty()) origin /= static_cast<double>(map.images.size());

  std::vector<std::vector<float>> keypoints(map.images.size()), points(map.images.size());
  std::vector<std::vector<int32_t>> links(map.images.size());
  std::vector<std::vector<uint8_t>> descriptors(map.images.size());
  std::vector<float> globals;
  std::vector<TensorView> tensors;
  nlohmann::json images = nlohmann::json::array();
  nlohmann::json checksums = nlohmann::json::object();
  auto add = [&](TensorView view) {
    checksums[view.name] = tensorChecksum(view);
    tensors.push_back(std::move(view));
  };

  for (size_t i = 0; i < map.images.size(); ++i) {
    const ClassicalMapImage& image = map.images[i];
    const size_t n = image.keypoints.size();
    const std::string where = "classical map image '" + image.name + "'";
    if (n < 2) throwInputError(file, 0, where + ": fewer than two keypoints");
    if (image.descriptors.rows != static_cast<int>(n) || image.descriptors.cols != 128 || image.descriptors.type() != CV_8U)
      throwInputError(file, 0, where + ": descriptors must be " + std::to_string(n) + "x128 bytes");
    if (image.points.size() != n || image.point_views.size() != n)
      throwInputError(file, 0, where + ": one point per keypoint expected");
    if (static_cast<size_t>(image.global_descriptor.size()) != descriptor_size)
      throwInputError(file, 0, where + ": global descriptor of the wrong length");
    for (const Eigen::Vector2d& p : image.keypoints) {
      keypoints[i].push_back(static_cast<float>(p.x()));
      keypoints[i].push_back(static_cast<float>(p.y()));
    }
    for (size_t k = 0; k < n; ++k) {
      const Eigen::Vector3d relative = image.point_views[k] > 0 ? Eigen::Vector3d(image.points[k] - origin)
                                                                : Eigen::Vector3d::Zero();
      points[i].insert(points[i].end(), {static_cast<float>(relative.x()), static_cast<float>(relative.y()),
                                         static_cast<float>(relative.z()), static_cast<float>(image.point_views[k])});
    }
    for (const KeypointLink& link : image.links)
      links[i].insert(links[i].end(), {static_cast<int32_t>(link.keypoint), static_cast<int32_t>(link.other_image),
                                       static_cast<int32_t>(link.other_keypoint)});
    const cv::Mat contiguous = image.descriptors.isContinuous() ? image.descriptors : image.descriptors.clone();
    descriptors[i].assign(contiguous.data, contiguous.data + contiguous.total());
    globals.insert(globals.end(), image.global_descriptor.data(), image.global_descriptor.data() + descriptor_size);

    const int64_t rows = static_cast<int64_t>(n);
    add(viewOf(tensorName("keypoints", i), DType::kF32, {rows, 2}, keypoints[i]));
    add(viewOf(tensorName("descriptors", i), DType::kU8, {rows, 128}, descriptors[i]));
    add(viewOf(tensorName("points", i), DType::kF32, {rows, kPointColumns}, points[i]));
    if (!links[i].empty())
      add(viewOf(tensorName("links", i), DType::kI32, {static_cast<int64_t>(image.links.size()), 3}, links[i]));
    const Intrinsics& k = image.camera;
    images.push_back({{"name", image.name},
                      {"camera_to_world", matrix4Json(image.camera_to_world.matrix())},
                      {"camera", {{"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy},
                                  {"width", k.width}, {"height", k.height}}},
                      {"working_scale", image.working_scale},
                      {"depth_lifted", image.depth_lifted},
                      {"keypoints", n},
                      {"links", image.links.size()}});
  }
  const auto& centres = map.vocabulary.centres();
  const std::vector<float> vocabulary(centres.data(), centres.data() + centres.size());
  add(viewOf("vocabulary", DType::kF32, {static_cast<int64_t>(centres.rows()), static_cast<int64_t>(centres.cols())},
             vocabulary));
  if (!map.images.empty())
    add(viewOf("global_descriptors", DType::kF32,
               {static_cast<int64_t>(map.images.size()), static_cast<int64_t>(descriptor_size)}, globals));

  const nlohmann::json body = {
      {"metric", map.metric},
      {"origin", {origin.x(), origin.y(), origin.z()}},
      {"sift", {{"max_image_size", map.sift.max_image_size}, {"max_features", map.sift.max_features},
                {"contrast_threshold", map.sift.contrast_threshold}, {"min_features", map.sift.min_features},
                {"low_contrast_threshold", map.sift.low_contrast_threshold},
                {"correct_upsampling_offset", map.sift.correct_upsampling_offset}}},
      {"ratio", map.ratio},
      {"images", images},
      {"checksums", checksums}};
  const std::string body_text = body.dump();
  const nlohmann::json header = {{"method", kMethod}, {"version", ClassicalMap::kVersion},
                                 {"body_checksum", hex64(fnv1a64(body_text))}};
  // The header checksummed too: a flipped byte in its "method" key read the map as FastForward's.
  std::map<std::string, std::string> metadata = mapMetadataEntries(header, path.string());
  metadata[kBodyKey] = body_text;
  writeSafetensors(path, tensors, metadata);
}

ClassicalMap readClassicalMap(const std::filesystem::path& path) {
  const std::string file = path.string();
  // A copy, not the file mapped: a map written over in place while a server reloaded it ended
  // the server (SIGBUS in the checksum pass); now the read fails as "changed while it was read".
  const auto archive = openSafetensors(path, FileMapping::kSnapshot);
  const nlohmann::json header_json = readMapMetadata(*archive, file);
  const MapHeader header = mapHeader(header_json, file);
  if (header.method != kMethod)
    throwInputError(file, 0, "map was built with the " + header.method +
                                 " method, not classical (localize it with the method it was built with)");
  if (header.version != ClassicalMap::kVersion)
    throwInputError(file, 0, "classical map version " + std::to_string(header.version) +
                                 " is not supported (this build reads version " + std::to_string(ClassicalMap::kVersion) +
                                 "; rebuild the map with ffloc map --method classical)");
  const auto body_entry = archive->metadata().find(kBodyKey);
  if (body_entry == archive->metadata().end()) throwInputError(file, 0, "classical map: metadata body missing");
  if (JsonFields(header_json, file, "").string("body_checksum") != hex64(fnv1a64(body_entry->second)))
    throwInputError(file, 0, "classical map: metadata checksum mismatch (the file is corrupted)");
  const nlohmann::json body = parseJson(body_entry->second, file + ": classical map metadata");

  ClassicalMap map;
  const JsonFields top(body, file, "");
  map.metric = top.boolean("metric");
  const std::vector<double> origin_values = top.numbers("origin");
  if (origin_values.size() != 3) top.fail("origin", "expected 3 numbers");
  const Eigen::Vector3d origin(origin_values[0], origin_values[1], origin_values[2]);
  if (!origin.allFinite()) top.fail("origin", "expected 3 finite numbers");
  const JsonFields sift(top.get("sift"), file, "sift");
  map.sift.max_image_size = static_cast<int>(sift.integer("max_image_size", 16, SiftOptions::kMaxImageSize));
  map.sift.max_features = static_cast<int>(sift.integer("max_features", 1, SiftOptions::kMaxFeatures));
  map.sift.contrast_threshold = sift.finiteNumber("contrast_threshold");
  // Maps written before the low-contrast fill-up described every image at contrast_threshold
  // alone; their queries must be described the same way.
  map.sift.min_features = sift.has("min_features") ? static_cast<int>(sift.integer("min_features", 0, SiftOptions::kMaxFeatures)) : 0;
  if (sift.has("low_contrast_threshold")) map.sift.low_contrast_threshold = sift.finiteNumber("low_contrast_threshold");
  // Likewise the keypoints of maps written before OpenCV's offset was corrected.
  map.sift.correct_upsampling_offset =
      sift.has("correct_upsampling_offset") && sift.boolean("correct_upsampling_offset");
  map.ratio = static_cast<float>(top.finiteNumber("ratio"));
  try {
    map.sift.check();
    if (!(map.ratio > 0 && map.ratio <= 1)) throw InputError("ratio: must be in (0, 1]");
  } catch (const InputError& e) {
    throwInputError(file, 0, std::string("classical map options: ") + e.what());
  }

  const nlohmann::json& checksums = top.get("checksums");
  if (!checksums.is_object()) top.fail("checksums", "expected an object of tensor name -> checksum");
  requireEveryRecordedTensor(*archive, checksums, file);
  auto tensor = [&](const std::string& name, DType dtype, const std::vector<int64_t>& shape) -> const TensorView& {
    if (!archive->contains(name)) throwInputError(file, 0, "tensor '" + name + "' missing");
    const TensorView& view = archive->at(name);
    checkTensorChecksum(name, tensorChecksum(view), checksums, file);
    if (view.dtype != dtype || view.shape != shape)
      throwInputError(file, 0, "tensor '" + name + "' has shape " + view.shapeString() + " " + toString(view.dtype) +
                                   ", expected another");
    return view;
  };
  auto floats = [](const TensorView& view) { return reinterpret_cast<const float*>(view.data); };

  const TensorView& vocabulary = archive->at("vocabulary");
  if (vocabulary.shape.size() != 2 || vocabulary.shape[1] != 128 || vocabulary.shape[0] < 1)
    throwInputError(file, 0, "tensor 'vocabulary' must be (words, 128)");
  tensor("vocabulary", DType::kF32, vocabulary.shape);
  VladVocabulary::RowMatrixXf centres(vocabulary.shape[0], 128);
  std::memcpy(centres.data(), vocabulary.data, vocabulary.nbytes);
  if (!centres.allFinite()) throwInputError(file, 0, "tensor 'vocabulary' holds values that are not finite");
  map.vocabulary = VladVocabulary(std::move(centres));
  const int64_t descriptor_size = static_cast<int64_t>(map.vocabulary.descriptorSize());

  const nlohmann::json& images = top.get("images");
  if (!images.is_array()) top.fail("images", "expected a list");
  const int64_t image_count = static_cast<int64_t>(images.size());
  const float* globals =
      image_count > 0 ? floats(tensor("global_descriptors", DType::kF32, {image_count, descriptor_size})) : nullptr;
  std::set<std::string> names;
  for (size_t i = 0; i < images.size(); ++i) {
    const JsonFields entry(images[i], file, "images[" + std::to_string(i) + "]");
    ClassicalMapImage image;
    image.name = entry.string("name");
    if (!names.insert(image.name).second) entry.fail("name", "'" + image.name + "' appears twice");
    const std::string named = "map image '" + image.name + "'";
    auto fail = [&](const std::string& what) { throwInputError(file, 0, named + ": " + what); };
    image.camera_to_world = rigidPose(entry, "camera_to_world");
    const JsonFields camera(entry.get("camera"), file, "images[" + std::to_string(i) + "].camera");
    image.camera.width = static_cast<int>(camera.integer("width", 1, 1 << 20));
    image.camera.height = static_cast<int>(camera.integer("height", 1, 1 << 20));
    image.camera.fx = camera.finiteNumber("fx");
    image.camera.fy = camera.finiteNumber("fy");
    image.camera.cx = camera.finiteNumber("cx");
    image.camera.cy = camera.finiteNumber("cy");
    if (!(image.camera.fx > 0 && image.camera.fy > 0)) fail("camera focal lengths must be positive");
    image.working_scale = entry.finiteNumber("working_scale");
    if (!(image.working_scale > 0 && image.working_scale <= 1)) entry.fail("working_scale", "must be in (0, 1]");
    image.depth_lifted = entry.boolean("depth_lifted");
    const int64_t n = entry.integer("keypoints", 2, 1 << 24);
    const int64_t link_count = entry.integer("links", 0, int64_t{1} << 31);

    const float* keypoints = floats(tensor(tensorName("keypoints", i), DType::kF32, {n, 2}));
    const TensorView& descriptors = tensor(tensorName("descriptors", i), DType::kU8, {n, 128});
    const float* points = floats(tensor(tensorName("points", i), DType::kF32, {n, kPointColumns}));
    image.keypoints.resize(n);
    image.points.resize(n);
    image.point_views.resize(n);
    for (int64_t p = 0; p < n; ++p) {
      image.keypoints[p] = {keypoints[2 * p], keypoints[2 * p + 1]};
      if (!image.keypoints[p].allFinite()) fail("keypoint " + std::to_string(p) + " is not finite");
      const float* row = points + kPointColumns * p;
      if (!(row[3] >= 0 && row[3] <= 255 && row[3] == std::floor(row[3])))
        fail("point " + std::to_string(p) + " has an invalid view count");
      image.point_views[p] = static_cast<uint8_t>(row[3]);
      image.points[p] = origin + Eigen::Vector3d(row[0], row[1], row[2]);
      if (image.point_views[p] > 0 && !image.points[p].allFinite())
        fail("point " + std::to_string(p) + " is not finite");
    }
    image.descriptors = cv::Mat(static_cast<int>(n), 128, CV_8U);
    std::memcpy(image.descriptors.data, descriptors.data, descriptors.nbytes);
    if (link_count > 0) {
      const int32_t* links = reinterpret_cast<const int32_t*>(tensor(tensorName("links", i), DType::kI32, {link_count, 3}).data);
      image.links.resize(link_count);
      for (int64_t l = 0; l < link_count; ++l) {
        const int32_t* row = links + 3 * l;
        if (row[0] < 0 || row[0] >= n || row[1] < 0 || row[1] >= image_count || row[2] < 0 ||
            static_cast<size_t>(row[1]) == i)
          fail("link " + std::to_string(l) + " points outside the map");
        image.links[l] = {static_cast<uint32_t>(row[0]), static_cast<uint32_t>(row[1]), static_cast<uint32_t>(row[2])};
      }
    }
    image.global_descriptor = Eigen::Map<const Eigen::VectorXf>(globals + i * descriptor_size, descriptor_size);
    if (!image.global_descriptor.allFinite()) fail("global descriptor is not finite");
    map.images.push_back(std::move(image));
  }
  // A link's far keypoint can only be checked once every image's size is known.
  for (const ClassicalMapImage& image : map.images)
    for (const KeypointLink& link : image.links)
      if (link.other_keypoint >= map.images[link.other_image].keypoints.size())
        throwInputError(file, 0, "map image '" + image.name + "': a link points past the keypoints of '" +
                                     map.images[link.other_image].name + "'");
  return map;
}

}  // namespace ffloc
