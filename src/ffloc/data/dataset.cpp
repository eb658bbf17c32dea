#include "ffloc/data/dataset.h"

#include <functional>
#include <set>
#include <utility>
#include <unordered_set>

#include "ffloc/core/error.h"
#include "ffloc/data/manifest.h"
#include "ffloc/data/pose_check.h"
#include "ffloc/data/readers.h"
#include "ffloc/io/image_format.h"
#include "ffloc/io/image_size.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

struct DatasetFormat {
  const char* name;
  const char* looks_for;  // for the "nothing matched" message
  std::function<bool(const fs::path&)> detect;
  std::function<Scene(const fs::path&)> read;
};

const std::vector<DatasetFormat>& formats() {
  static const std::vector<DatasetFormat> kFormats = {
      {"manifest", "manifest.json with \"format\": \"ffloc-manifest\"",
       [](const fs::path& dir) { return isManifestFile(dir / kManifestFileName); },
       [](const fs::path& dir) { return readManifest(dir / kManifestFileName); }},
      {"7scenes", "frame-XXXXXX.pose.txt (in the folder, rgbd-frames/ or seq-XX/) or TrainSplit.txt/TestSplit.txt",
       looksLikeSevenScenes, readSevenScenes},
      {"nerf", "transforms.json or transforms_train.json", looksLikeNerf, readNerf},
      {"colmap", "images.txt/images.bin in the folder or sparse/0, sparse, reconstruction, model", looksLikeColmap,
       readColmap},
      {"strecha", "gt_dense_cameras/*.camera", looksLikeStrecha, readStrecha},
      {"cambridge", "dataset_train.txt or dataset_test.txt", looksLikeCambridge, readCambridge},
      {"kapture", "sensors/sensors.txt in the folder or in mapping/, query/", looksLikeKapture, readKapture},
      {"mapfree", "intrinsics.txt and seq0/", looksLikeMapFree, readMapFree},
      {"ace", "train/ or test/ with rgb/ and poses/", looksLikeAceLayout, readAceLayout},
      {"rio10", "seqXX_YY/ with camera.yaml, or seqXX_YY/ and intrinsics.txt in the folder or above it", looksLikeRio10, readRio10},
      {"indoor6", "images/*.intrinsics.txt", looksLikeIndoor6, readIndoor6},
  };
  return kFormats;
}

void requireUniqueNames(const Scene& scene) {
  std::unordered_set<std::string> names;
  for (const Frame& frame : scene.frames)
    if (!names.insert(frame.name).second)
      throwInputError(scene.root.string(), 0, "two frames share the image name '" + frame.name + "'");
}

// Every frame's intrinsics, mapping or query, pass the focal length and principal point checks a
// query given on the command line passes, for the image size the intrinsics give (the image is
// held to that size when it is read), and every camera centre what a parsed pose matrix passes
// (some formats give centres, not matrices): a mapping frame that fails would otherwise give a map
// that refuses every query, or one that cannot be read back.
void requirePlausibleFrames(const Scene& scene) {
  // Every image's size is read (a NeRF "w" and "h" swapped, a COLMAP camera of twice the images'
  // size, or one image of another size or not an image at all passed, and a converted copy then
  // failed its own reader): from the PNG or JPEG header, and where that does not settle it (EXIF,
  // other formats, the first image of each size) as readImageSize reads it, decoding if need be.
  std::set<std::pair<int, int>> sizes_seen;
  for (const Frame& frame : scene.frames) {
    const std::string where = "frame '" + frame.name + "': ";
    const cv::Size claimed(frame.intrinsics.width, frame.intrinsics.height);
    const bool first_of_its_size = sizes_seen.insert({claimed.width, claimed.height}).second;
    const std::optional<ImageHeader> header = first_of_its_size ? std::nullopt : fileImageHeader(frame.image_path);
    try {
      if (!first_of_its_size && !header) {
        // Not a PNG or JPEG: its signature is checked, not decoded for every frame (TIFF, BMP).
        requireDecodableImageFile(frame.image_path, "cannot decode image");
      } else if (first_of_its_size || header->with_exif || header->size != claimed) {
        // As decoded: a JPEG of the claimed size stored but turned by its EXIF orientation passed.
        const cv::Size image = readImageSize(frame.image_path);
        if (image != claimed)
          throw InputError("the intrinsics are for a " + std::to_string(claimed.width) + "x" +
                           std::to_string(claimed.height) + " image, but " + frame.image_path.string() + " is " +
                           std::to_string(image.width) + "x" + std::to_string(image.height));
      }
    } catch (const InputError& error) {
      throwInputError(scene.root.string(), 0, where + error.what());
    }
    // A depth map is read against the image as decoded: an image turned by its EXIF orientation
    // and its depth map not turned alike pair each pixel with another's depth. Turned by 180
    // degrees the size still fits, and every mapping frame so was mapped without a word, its
    // queries `localized` 179 deg off (an outside probe).
    if (frame.depth && decodingTurnsImage(frame.image_path) && !decodingTurnsImage(frame.depth->path))
      throwInputError(scene.root.string(), 0,
                      where + frame.image_path.string() + " is turned by its EXIF orientation as it is decoded, and "
                      "its depth map " + frame.depth->path.string() + " is not: each pixel would get another's depth. "
                      "Store the image upright (its pose and intrinsics then of the upright image) with its depth "
                      "turned alike, or remove the orientation tag");
    // After the size: intrinsics for an image of another size were judged as they stood, and a
    // lens that folds the image they describe was blamed for what a wrong size did.
    try {
      checkIntrinsicsFitImage(frame.intrinsics, frame.intrinsics.width, frame.intrinsics.height);
    } catch (const InputError& error) {
      throwInputError(scene.root.string(), 0, where + "intrinsics: " + error.what());
    }
    const std::string centre = cameraCentreProblem(frame.camera_to_world.t);
    if (!centre.empty()) throwInputError(scene.root.string(), 0, where + centre);
  }
}

}  // namespace

std::vector<std::string> datasetFormats() {
  std::vector<std::string> names;
  for (const auto& format : formats()) names.push_back(format.name);
  return names;
}

namespace {

// std::filesystem reports a symbolic link loop or a folder it may not read by throwing; each is
// a problem with the input, and names its path.
template <typename Action>
auto withFilesystemErrorsAsInputErrors(Action&& action) {
  try {
    return action();
  } catch (const fs::filesystem_error& error) {
    throwInputError(error.path1().string(), 0, error.code().message());
  }
}

std::string detectFormat(const fs::path& dir) {
  std::error_code error;
  const fs::file_status status = fs::status(dir, error);
  if (status.type() == fs::file_type::not_found) throwInputError(dir.string(), 0, "dataset folder not found");
  if (error) throwInputError(dir.string(), 0, "dataset folder: " + error.message());
  if (status.type() != fs::file_type::directory) throwInputError(dir.string(), 0, "not a folder (give the dataset's folder)");
  for (const auto& format : formats())
    if (format.detect(dir)) return format.name;
  std::string looked_for;
  for (const auto& format : formats()) looked_for += std::string("\n  ") + format.name + ": " + format.looks_for;
  throwInputError(dir.string(), 0, "unknown dataset format; looked for:" + looked_for);
}

Scene loadKnownFormat(const fs::path& dataset_dir, const std::string& format) {
  // Absolute and normalised, so image paths compare equal however the folder was named.
  fs::path dir = fs::absolute(dataset_dir).lexically_normal();
  if (dir.filename().empty()) dir = dir.parent_path();
  const std::string name = format == "auto" ? detectFormat(dir) : format;
  for (const auto& candidate : formats()) {
    if (name != candidate.name) continue;
    if (!fs::is_directory(dir)) throwInputError(dir.string(), 0, "dataset folder not found");
    Scene scene = candidate.read(dir);
    // A NeRF file of no frames converted to a dataset of none, exit 0.
    if (scene.frames.empty()) throwInputError(dir.string(), 0, "the " + name + " dataset holds no frame");
    requireUniqueNames(scene);
    requirePlausibleFrames(scene);
    applySplitFiles(scene);
    return scene;
  }
  std::string known;
  for (const auto& candidate : datasetFormats()) known += (known.empty() ? "" : ", ") + candidate;
  throwInputError(dir.string(), 0, "unknown dataset format '" + name + "' (known: auto, " + known + ")");
}

}  // namespace

std::string detectDatasetFormat(const fs::path& dir) {
  return withFilesystemErrorsAsInputErrors([&] { return detectFormat(dir); });
}

Scene loadDataset(const fs::path& dataset_dir, const std::string& format) {
  return withFilesystemErrorsAsInputErrors([&] { return loadKnownFormat(dataset_dir, format); });
}

}  // namespace ffloc
