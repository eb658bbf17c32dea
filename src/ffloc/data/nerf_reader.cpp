#include <algorithm>
#include <cmath>

#include "ffloc/core/error.h"
#include "ffloc/core/number_text.h"
#include "ffloc/io/image_size.h"
#include "ffloc/io/json_fields.h"
#include "ffloc/data/pose_check.h"
#include "ffloc/data/readers.h"
#include "ffloc/geometry/camera.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// A frame's value of an intrinsics key: its own (per-frame override) or the file's.
class CameraKeys {
 public:
  CameraKeys(const JsonFields& top, const JsonFields& frame) : top_(top), frame_(frame) {}
  bool has(const std::string& key) const { return frame_.has(key) || top_.has(key); }
  double number(const std::string& key) const { return frame_.has(key) ? frame_.number(key) : top_.number(key); }
  std::string string(const std::string& key) const {
    return frame_.has(key) ? frame_.string(key) : top_.string(key);
  }
  const JsonFields& owner(const std::string& key) const { return frame_.has(key) ? frame_ : top_; }

 private:
  const JsonFields& top_;
  const JsonFields& frame_;
};

// Blender-style NeRF data often writes file_path without an extension ("./train/r_0").
fs::path resolveImage(const fs::path& folder, const std::string& file_path, const JsonFields& frame) {
  const fs::path base = (folder / file_path).lexically_normal();
  if (fs::is_regular_file(base)) return base;
  for (const char* extension : {".png", ".jpg", ".jpeg", ".JPG", ".PNG", ".JPEG"}) {
    fs::path candidate = base;
    candidate += extension;
    if (fs::is_regular_file(candidate)) return candidate;
  }
  frame.fail("file_path", "image '" + base.string() + "' not found (also tried .png, .jpg, .jpeg)");
}

// OpenCV reads no image with a side beyond this (CV_IO_MAX_IMAGE_WIDTH).
constexpr double kMaxImageSide = 1 << 20;

// "w" or "h": checked before the conversion to int, which is undefined for values an int cannot
// hold. Some writers store them as floats ("w": 800.0), which is fine when whole.
int imageSide(const CameraKeys& keys, const std::string& key) {
  const double side = keys.number(key);
  if (!(side >= 1 && side <= kMaxImageSide) || side != std::floor(side))
    keys.owner(key).fail(key, "expected a whole number of pixels in [1, " + std::to_string(static_cast<int>(kMaxImageSide)) + "]");
  return static_cast<int>(side);
}

Intrinsics readCamera(const CameraKeys& keys, const fs::path& image_path) {
  if (keys.has("camera_model")) {
    const std::string model = keys.string("camera_model");
    if (model != "OPENCV" && model != "PINHOLE" && model != "SIMPLE_PINHOLE")
      keys.owner("camera_model").fail("camera_model", "unsupported camera model '" + model + "' (supported: OPENCV, PINHOLE, SIMPLE_PINHOLE)");
  }
  if (keys.has("is_fisheye") && keys.owner("is_fisheye").boolean("is_fisheye"))
    keys.owner("is_fisheye").fail("is_fisheye", "fisheye cameras are not supported");

  Intrinsics intrinsics;
  if (keys.has("w") && keys.has("h")) {
    intrinsics.width = imageSide(keys, "w");
    intrinsics.height = imageSide(keys, "h");
  } else {
    const cv::Size size = readImageSize(image_path);
    intrinsics.width = size.width;
    intrinsics.height = size.height;
  }
  const double w = intrinsics.width, h = intrinsics.height;
  // Radians across the image: 40 (degrees given by mistake) gave a focal length of 241 px where
  // 1375 was meant, and pi one of 1e-12, without a word.
  const auto fieldOfView = [&](const char* key) {
    const double angle = keys.number(key);
    if (!(angle > 0 && angle < M_PI)) keys.owner(key).fail(key, "must be an angle in radians in (0, pi), got " + std::to_string(angle));
    return angle;
  };
  if (keys.has("fl_x")) {
    intrinsics.fx = keys.number("fl_x");
  } else if (keys.has("camera_angle_x")) {
    intrinsics.fx = 0.5 * w / std::tan(0.5 * fieldOfView("camera_angle_x"));
  } else {
    keys.owner("fl_x").fail("fl_x", "missing focal length (need fl_x or camera_angle_x)");
  }
  if (keys.has("fl_y")) {
    intrinsics.fy = keys.number("fl_y");
  } else if (keys.has("camera_angle_y")) {
    intrinsics.fy = 0.5 * h / std::tan(0.5 * fieldOfView("camera_angle_y"));
  } else {
    intrinsics.fy = intrinsics.fx;
  }
  // NeRF-family code casts rays through (i + 0.5, j + 0.5) against a principal point measured
  // from the image corner (COLMAP's convention); OpenCV puts pixel centres at integers.
  intrinsics.cx = (keys.has("cx") ? keys.number("cx") : 0.5 * w) - 0.5;
  intrinsics.cy = (keys.has("cy") ? keys.number("cy") : 0.5 * h) - 0.5;

  const char* const distortion_keys[] = {"k1", "k2", "p1", "p2", "k3"};
  std::vector<double> distortion;
  for (const char* key : distortion_keys) distortion.push_back(keys.has(key) ? keys.number(key) : 0.0);
  if (distortion[4] == 0.0) distortion.pop_back();
  bool distorted = false;
  for (double d : distortion) distorted = distorted || d != 0.0;
  if (distorted) intrinsics.distortion = distortion;
  for (const char* key : {"k4", "k5", "k6"})
    if (keys.has(key) && keys.number(key) != 0.0)
      keys.owner(key).fail(key, "rational/fisheye distortion terms are not supported");

  for (const auto& [key, focal] : {std::pair{"fl_x", intrinsics.fx}, {"fl_y", intrinsics.fy}})
    if (!(focal > 0)) keys.owner(key).fail(key, "the focal length must be positive, got " + formatNumber(focal));
  // The distortion is judged over the image the rest describes: a wrong size, focal length or
  // principal point was blamed on a coefficient ("field 'k2': ... folds the image" for "w" twice
  // the image's). Those are named first, by the dataset's checks of every frame.
  // The size from the image's header (no decoding per frame); turned by EXIF, it is not judged.
  const auto sizeFitsItsImage = [&] {
    const std::optional<ImageHeader> header = fileImageHeader(image_path);
    return !header || header->with_exif || header->size == cv::Size(intrinsics.width, intrinsics.height);
  };
  const std::string problem = distorted && sizeFitsItsImage() ? distortionProblem(intrinsics) : std::string();
  if (!problem.empty()) {
    // The coefficients act together; the field named is the one farthest from 0, the likeliest
    // culprit (the message names every coefficient that is not 0).
    const size_t culprit = std::max_element(distortion.begin(), distortion.end(),
                                            [](double a, double b) { return std::abs(a) < std::abs(b); }) -
                           distortion.begin();
    keys.owner(distortion_keys[culprit]).fail(distortion_keys[culprit], problem);
  }
  return intrinsics;
}

void readTransformsFile(const fs::path& file, const fs::path& root, Split split, Scene& scene) {
  const json document = parseJsonFile(file);
  const JsonFields top(document, file, "");
  const json& frames = top.get("frames");
  if (!frames.is_array()) top.fail("frames", "expected an array");
  const fs::path folder = file.parent_path();
  // T_cv = T_gl * diag(1, -1, -1, 1): OpenGL cameras look down -z with y up.
  const Eigen::Vector3d flip(1, -1, -1);
  for (size_t i = 0; i < frames.size(); ++i) {
    const JsonFields entry(frames[i], file, "frames[" + std::to_string(i) + "]");
    Frame frame;
    frame.image_path = resolveImage(folder, entry.string("file_path"), entry);
    frame.name = frameName(frame.image_path, root);
    frame.intrinsics = readCamera(CameraKeys(top, entry), frame.image_path);
    const Eigen::Matrix4d T = entry.matrix4("transform_matrix");
    const std::string problem = poseMatrixProblem(T);
    if (!problem.empty()) entry.fail("transform_matrix", problem);
    Pose pose = Pose::fromMatrix(T);
    projectToRotation(pose.R);
    pose.R = pose.R * flip.asDiagonal();
    frame.camera_to_world = pose;
    frame.split = split;
    scene.frames.push_back(std::move(frame));
  }
}

}  // namespace

bool looksLikeNerf(const fs::path& dir) {
  return fs::is_regular_file(dir / "transforms.json") || fs::is_regular_file(dir / "transforms_train.json");
}

Scene readNerf(const fs::path& dir) {
  Scene scene = emptyScene(dir, "nerf", false);
  if (fs::exists(dir / "transforms.json")) {
    readTransformsFile(dir / "transforms.json", dir, Split::kUnassigned, scene);
  } else {
    // The Blender/LLFF synthetic layout: one file per split.
    readTransformsFile(dir / "transforms_train.json", dir, Split::kMapping, scene);
    if (fs::exists(dir / "transforms_val.json"))
      readTransformsFile(dir / "transforms_val.json", dir, Split::kUnassigned, scene);
    if (fs::exists(dir / "transforms_test.json"))
      readTransformsFile(dir / "transforms_test.json", dir, Split::kQuery, scene);
  }
  return scene;
}

}  // namespace ffloc
