// Indoor6 (Do et al., CVPR 2022, "Learning to Detect Scene Landmarks for Camera Localization"),
// as its authors publish it: one folder per scene with images/image-NNNNNN.color.jpg, and beside
// each image .pose.txt (3x4 world-to-camera [R|t]) and .intrinsics.txt ("W H f cx cy", the
// COLMAP-derived camera); the split lists <scene>_train.txt, <scene>_val.txt, <scene>_test.txt
// name the images (the same lists as train_test_val.pkl, which is a Python pickle and not read).
#include <algorithm>
#include <cstdio>
#include <map>

#include "ffloc/core/error.h"
#include "ffloc/data/dataset_writers.h"
#include "ffloc/data/format_io.h"
#include "ffloc/data/pose_check.h"
#include "ffloc/data/readers.h"
#include "ffloc/data/text_file.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

constexpr const char* kColourSuffix = ".color.jpg";
constexpr const char* kPoseSuffix = ".pose.txt";
constexpr const char* kIntrinsicsSuffix = ".intrinsics.txt";
const std::pair<const char*, Split> kSplitLists[] = {
    {"_train.txt", Split::kMapping}, {"_test.txt", Split::kQuery}, {"_val.txt", Split::kUnassigned}};


// "W H f cx cy" and, when present, a sixth value: the radial k of COLMAP's SIMPLE_RADIAL.
// The cameras come from COLMAP, whose top-left pixel centre is (0.5, 0.5).
Intrinsics readIntrinsics(const fs::path& file) {
  const auto lines = contentLines(readTextLines(file), true);
  if (lines.size() != 1) throwInputError(file.string(), 0, "expected one line 'W H f cx cy'");
  const auto values = parseNumbers(lines[0], file);
  if (values.size() != 5 && values.size() != 6)
    throwInputError(file.string(), lines[0].number,
                    "expected 'W H f cx cy [k]', found " + std::to_string(values.size()) + " numbers");
  Intrinsics K;
  K.width = static_cast<int>(values[0]);
  K.height = static_cast<int>(values[1]);
  K.fx = K.fy = values[2];
  K.cx = values[3] - 0.5;
  K.cy = values[4] - 0.5;
  if (values.size() == 6 && values[5] != 0) K.distortion = {values[5], 0, 0, 0};
  if (!K.isValid() || K.width != values[0] || K.height != values[1])
    throwInputError(file.string(), lines[0].number, "invalid camera (integer size and positive focal length needed)");
  return K;
}

Pose readWorldToCameraPose(const fs::path& file) {
  const MatrixFile matrix = readMatrixFile(file, 3, 4);
  Eigen::Matrix4d world_to_camera = Eigen::Matrix4d::Identity();
  world_to_camera.topRows<3>() = matrix.values;
  return validatedPose(world_to_camera, file, matrix.row_lines.back()).inverse();
}

std::vector<fs::path> splitLists(const fs::path& dir) {
  std::vector<fs::path> lists;
  for (const auto& entry : fs::directory_iterator(dir))
    for (const auto& [suffix, split] : kSplitLists)
      if (entry.is_regular_file() && endsWith(entry.path().filename().string(), suffix)) lists.push_back(entry.path());
  std::sort(lists.begin(), lists.end());
  return lists;
}

Split splitOfList(const fs::path& list) {
  for (const auto& [suffix, split] : kSplitLists)
    if (endsWith(list.filename().string(), suffix)) return split;
  return Split::kUnassigned;
}

}  // namespace

bool looksLikeIndoor6(const fs::path& dir) {
  if (!fs::is_directory(dir / "images")) return false;
  for (const auto& entry : fs::directory_iterator(dir / "images"))
    if (endsWith(entry.path().filename().string(), kIntrinsicsSuffix)) return true;
  return false;
}

Scene readIndoor6(const fs::path& dir) {
  Scene scene = emptyScene(dir, "indoor6", true);
  const fs::path images_dir = dir / "images";
  std::vector<fs::path> images;
  for (const auto& entry : fs::directory_iterator(images_dir))
    if (endsWith(entry.path().filename().string(), kColourSuffix)) images.push_back(entry.path());
  std::sort(images.begin(), images.end());
  std::map<std::string, size_t> index_of;  // image file name -> frame
  for (const fs::path& image : images) {
    const std::string name = image.filename().string();
    const std::string stem = name.substr(0, name.size() - std::string(kColourSuffix).size());
    Frame frame;
    frame.image_path = image;
    frame.name = frameName(image, dir);
    const fs::path intrinsics_file = images_dir / (stem + kIntrinsicsSuffix);
    const fs::path pose_file = images_dir / (stem + kPoseSuffix);
    for (const fs::path& companion : {intrinsics_file, pose_file})
      if (!fs::exists(companion)) throwInputError(image.string(), 0, "no " + companion.filename().string() + " beside it");
    frame.intrinsics = readIntrinsics(intrinsics_file);
    requireImageSize(image, frame.intrinsics.width, frame.intrinsics.height, intrinsics_file.string(), 1);
    frame.camera_to_world = readWorldToCameraPose(pose_file);
    index_of[name] = scene.frames.size();
    scene.frames.push_back(std::move(frame));
  }
  if (scene.frames.empty()) throwInputError(images_dir.string(), 0, "no image-*.color.jpg images");
  for (const fs::path& list : splitLists(dir)) {
    for (const auto& line : contentLines(readTextLines(list), true)) {
      const auto tokens = splitWhitespace(line.text);
      const std::string name = fs::path(tokens.front()).filename().string();
      const auto frame = index_of.find(name);
      if (tokens.size() != 1 || frame == index_of.end())
        throwInputError(list.string(), line.number, "'" + line.text + "' is not an image in " + images_dir.string());
      scene.frames[frame->second].split = splitOfList(list);
    }
  }
  return scene;
}

std::vector<std::string> writeIndoor6(const Scene& scene, const fs::path& out) {
  for (const Frame& frame : scene.frames) {
    const auto& d = frame.intrinsics.distortion;
    if (frame.intrinsics.fx != frame.intrinsics.fy)
      throwInputError(frame.name, 0, "has fx != fy, and Indoor6 stores one focal length");
    if (std::any_of(d.begin() + std::min<size_t>(1, d.size()), d.end(), [](double v) { return v != 0; }))
      throwInputError(frame.name, 0, "has distortion beyond a radial k1, which Indoor6 cannot store");
  }
  const std::string scene_name = out.filename().string();
  std::map<Split, std::string> lists;
  std::vector<std::string> names;
  for (size_t i = 0; i < scene.frames.size(); ++i) {
    const Frame& frame = scene.frames[i];
    char stem[32];
    std::snprintf(stem, sizeof(stem), "image-%06zu", i);
    const fs::path folder = out / "images";
    copyFrameImage(frame, folder / (std::string(stem) + kColourSuffix), true);
    const Intrinsics& K = frame.intrinsics;
    std::string intrinsics = std::to_string(K.width) + " " + std::to_string(K.height) + " " + formatNumber(K.fx) +
                             " " + formatNumber(K.cx + 0.5) + " " + formatNumber(K.cy + 0.5);
    if (!K.distortion.empty()) intrinsics += " " + formatNumber(K.distortion[0]);
    writeTextCreatingFolders(folder / (std::string(stem) + kIntrinsicsSuffix), intrinsics + "\n");
    const Eigen::Matrix4d world_to_camera = frame.camera_to_world.inverse().matrix();
    writeTextCreatingFolders(folder / (std::string(stem) + kPoseSuffix), matrixText(world_to_camera.topRows<3>()));
    lists[frame.split] += std::string(stem) + kColourSuffix + "\n";
    names.push_back(std::string("images/") + stem + kColourSuffix);
  }
  for (const auto& [suffix, split] : kSplitLists)
    if (lists.count(split)) writeTextCreatingFolders(out / (scene_name + suffix), lists[split]);
  return names;
}

}  // namespace ffloc
