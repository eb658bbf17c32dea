#include <algorithm>
#include <cstdio>
#include <map>

#include "ffloc/core/error.h"
#include "ffloc/io/image_size.h"
#include "ffloc/data/pose_check.h"
#include "ffloc/data/readers.h"
#include "ffloc/data/text_file.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

bool isPoseFile(const fs::path& path) {
  const std::string name = path.filename().string();
  const std::string suffix = ".pose.txt";
  return name.rfind("frame-", 0) == 0 && name.size() > suffix.size() &&
         name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
}

bool hasPoseFiles(const fs::path& dir) {
  if (!fs::is_directory(dir)) return false;
  for (const auto& entry : fs::directory_iterator(dir))
    if (isPoseFile(entry.path())) return true;
  return false;
}

std::vector<fs::path> sequenceFolders(const fs::path& dir) {
  std::vector<fs::path> folders;
  if (!fs::is_directory(dir)) return folders;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.is_directory() && entry.path().filename().string().rfind("seq-", 0) == 0) folders.push_back(entry.path());
  std::sort(folders.begin(), folders.end());
  return folders;
}

// The 7-Scenes web page documents these for every scene. They are the depth camera's: RGB is
// not calibrated separately, and its images are not registered to the depth. The original
// layout ships no intrinsics file.
Intrinsics defaultIntrinsics() {
  Intrinsics K;
  K.fx = K.fy = 585.0;
  K.cx = 320.0;
  K.cy = 240.0;
  K.width = 640;
  K.height = 480;
  return K;
}

Intrinsics readIntrinsicsFile(const fs::path& file) {
  const Eigen::MatrixXd K = readMatrixFile(file, 3, 3).values;
  if (K(0, 1) != 0 || K(1, 0) != 0 || K(2, 0) != 0 || K(2, 1) != 0 || K(2, 2) != 1)
    throwInputError(file.string(), 0, "not a pinhole K matrix (expected fx 0 cx / 0 fy cy / 0 0 1)");
  Intrinsics intrinsics;
  intrinsics.fx = K(0, 0);
  intrinsics.fy = K(1, 1);
  intrinsics.cx = K(0, 2);
  intrinsics.cy = K(1, 2);
  if (!(intrinsics.fx > 0 && intrinsics.fy > 0)) throwInputError(file.string(), 0, "focal lengths must be positive");
  return intrinsics;
}

// The colour camera of 7-Scenes' Kinect, as DSAC* and ACE use it: focal length 525 px at the
// depth camera's principal point. Measured here: with 585 for the colour images as well, the
// classical method's median rotation error on the redkitchen query split is 3.6 deg, with 525
// it is 2.3 deg (docs/classical.md).
constexpr double kSevenScenesColourFocal = 525.0;

bool isSevenScenesDepthCamera(const Intrinsics& k) {
  const Intrinsics d = defaultIntrinsics();
  return k.fx == d.fx && k.fy == d.fy && k.cx == d.cx && k.cy == d.cy;
}

// Original 7-Scenes text: tab-separated, `e-001` exponents, trailing tabs, CRLF.
Pose readPoseFile(const fs::path& file) {
  const MatrixFile matrix = readMatrixFile(file, 4, 4);
  return validatedPose(matrix.values, file, matrix.row_lines);
}

// Frames of one folder, sorted by name; `name_root` is what Frame::name is relative to.
std::vector<Frame> readFrameFolder(const fs::path& folder, const fs::path& name_root, const Intrinsics& camera) {
  std::vector<fs::path> pose_files;
  for (const auto& entry : fs::directory_iterator(folder))
    if (isPoseFile(entry.path())) pose_files.push_back(entry.path());
  std::sort(pose_files.begin(), pose_files.end());
  std::vector<Frame> frames;
  for (const auto& pose_file : pose_files) {
    const std::string file_name = pose_file.filename().string();
    const std::string stem = file_name.substr(0, file_name.find('.'));  // "frame-000000"
    Frame frame;
    for (const char* extension : {".color.png", ".color.jpg"}) {
      if (!fs::exists(folder / (stem + extension))) continue;
      // The PNG was taken without a word, and a split list naming the JPEG refused it as no frame.
      if (!frame.image_path.empty())
        throwInputError(pose_file.string(), 0, "two colour images, " + frame.image_path.filename().string() + " and " +
                                                   stem + extension + "; keep one");
      frame.image_path = folder / (stem + extension);
    }
    if (frame.image_path.empty())
      throwInputError(pose_file.string(), 0, "no colour image " + stem + ".color.png or .color.jpg beside it");
    frame.name = frameName(frame.image_path, name_root);
    frame.intrinsics = camera;
    const cv::Size size = readImageSize(frame.image_path);
    // The documented camera is of 640 x 480 frames: another size got its principal point (320,
    // 240) in a corner without a word, or had its depth map blamed.
    if (isSevenScenesDepthCamera(camera) &&
        (size.width != defaultIntrinsics().width || size.height != defaultIntrinsics().height))
      throwInputError(frame.image_path.string(), 0,
                      "image is " + std::to_string(size.width) + "x" + std::to_string(size.height) +
                          ", but 7-Scenes' intrinsics are of 640x480 images; give this size's in camera-intrinsics.txt");
    frame.intrinsics.width = size.width;
    frame.intrinsics.height = size.height;
    // 7-Scenes' own intrinsics are the depth camera's: the colour camera gets its own, and the
    // depth is registered to it when read. Other intrinsics are taken to be the colour camera's
    // with registered depth.
    std::optional<Intrinsics> depth_camera;
    if (isSevenScenesDepthCamera(camera)) {
      depth_camera = frame.intrinsics;
      frame.intrinsics.fx = frame.intrinsics.fy = kSevenScenesColourFocal;
    }
    frame.camera_to_world = readPoseFile(pose_file);
    const fs::path depth_path = folder / (stem + ".depth.png");
    if (fs::exists(depth_path)) {
      DepthSource depth;  // uint16 millimetres, 0 and 65535 invalid: the defaults
      depth.path = depth_path;
      depth.camera = depth_camera;
      frame.depth = depth;
    }
    frames.push_back(std::move(frame));
  }
  return frames;
}

// "sequence2" -> "seq-02", line by line, naming the file and line of anything else.
std::map<std::string, int> readSequenceList(const fs::path& file, const fs::path& root) {
  std::map<std::string, int> sequences;
  for (const auto& line : contentLines(readTextLines(file), false)) {
    const auto tokens = splitWhitespace(line.text);
    const std::string& token = tokens.front();
    if (tokens.size() != 1 || token.rfind("sequence", 0) != 0)
      throwInputError(file.string(), line.number, "expected 'sequenceN', got '" + line.text + "'");
    const long number = parseInteger(token.substr(8), file, line.number, "sequence number");
    char folder[32];
    std::snprintf(folder, sizeof(folder), "seq-%02ld", number);
    if (!fs::is_directory(root / folder))
      throwInputError(file.string(), line.number, "'" + token + "' names missing folder " + (root / folder).string());
    sequences[folder] = line.number;
  }
  return sequences;
}

}  // namespace

bool looksLikeSevenScenes(const fs::path& dir) {
  if (hasPoseFiles(dir) || hasPoseFiles(dir / "rgbd-frames")) return true;
  if (fs::exists(dir / "TrainSplit.txt") || fs::exists(dir / "TestSplit.txt")) return true;
  for (const auto& folder : sequenceFolders(dir))
    if (hasPoseFiles(folder)) return true;
  return false;
}

Scene readSevenScenes(const fs::path& dir) {
  Scene scene = emptyScene(dir, "7scenes", true);

  const fs::path intrinsics_file = dir / "camera-intrinsics.txt";
  // A link to no file is a file meant but not there: read, it says so (the defaults were taken).
  const Intrinsics camera = fs::exists(intrinsics_file) || fs::is_symlink(intrinsics_file)
                                ? readIntrinsicsFile(intrinsics_file)
                                : defaultIntrinsics();

  if (hasPoseFiles(dir) || hasPoseFiles(dir / "rgbd-frames")) {
    scene.frames = readFrameFolder(hasPoseFiles(dir) ? dir : dir / "rgbd-frames", dir, camera);
    return scene;
  }

  std::map<std::string, Split> split_of;
  for (const auto& [file_name, split] : {std::pair{"TrainSplit.txt", Split::kMapping}, {"TestSplit.txt", Split::kQuery}}) {
    if (!fs::exists(dir / file_name)) continue;
    for (const auto& [folder, line] : readSequenceList(dir / file_name, dir)) {
      if (split_of.count(folder))
        throwInputError((dir / file_name).string(), line, folder + " is in both TrainSplit.txt and TestSplit.txt");
      split_of[folder] = split;
    }
  }
  const auto folders = sequenceFolders(dir);
  for (const auto& folder : folders) {
    auto frames = readFrameFolder(folder, dir, camera);
    const auto split = split_of.find(folder.filename().string());
    for (auto& frame : frames) {
      if (split != split_of.end()) frame.split = split->second;
      scene.frames.push_back(std::move(frame));
    }
  }
  if (scene.frames.empty())
    throwInputError(dir.string(), 0, "no 7-Scenes frames (frame-XXXXXX.pose.txt) in it or in its seq-XX folders");
  return scene;
}

}  // namespace ffloc
