// RIO10 (Wald et al., ECCV 2020; WaldJohannaU/RIO10): a scene folder seqXX/ holding sequences
// seqXX_YY/ of frame-NNNNNN.{color.jpg, pose.txt, rendered.depth.png}. seqXX_01 is the
// training sequence, seqXX_02 the validation one (the paper's queries), the others the hidden
// test sequences, which ship without poses. Intrinsics come from the authors' intrinsics.txt
// (data/intrinsics.txt in their repository, beside the scene folders) or from a camera.yaml in
// the sequence, which the authors do not describe.
#include <algorithm>
#include <cstdio>
#include <map>
#include <optional>
#include <regex>

#include "ffloc/core/error.h"
#include "ffloc/data/dataset_writers.h"
#include "ffloc/data/format_io.h"
#include "ffloc/io/image_size.h"
#include "ffloc/data/pose_check.h"
#include "ffloc/data/readers.h"
#include "ffloc/data/text_file.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

constexpr const char* kCameraFile = "camera.yaml";
constexpr const char* kIntrinsicsFile = "intrinsics.txt";
constexpr const char* kColourSuffix = ".color.jpg";
constexpr const char* kPoseSuffix = ".pose.txt";
constexpr const char* kDepthSuffix = ".rendered.depth.png";

bool isSequenceName(const std::string& name) {
  static const std::regex pattern("seq[0-9]+_[0-9]+");
  return std::regex_match(name, pattern);
}

std::vector<fs::path> sequenceFolders(const fs::path& dir) {
  std::vector<fs::path> folders;
  if (!fs::is_directory(dir)) return folders;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.is_directory() && isSequenceName(entry.path().filename().string())) folders.push_back(entry.path());
  std::sort(folders.begin(), folders.end());
  return folders;
}

// The authors keep intrinsics.txt beside the scene folders (their evaluator reads
// <data>/intrinsics.txt and <data>/seqXX/seqXX_YY/); one in the scene folder itself comes first.
std::optional<fs::path> intrinsicsFile(const fs::path& dir) {
  fs::path scene = fs::absolute(dir).lexically_normal();
  if (scene.filename().empty()) scene = scene.parent_path();  // "dir/" ends in an empty part
  for (const fs::path& folder : {scene, scene.parent_path()})
    if (fs::is_regular_file(folder / kIntrinsicsFile)) return folder / kIntrinsicsFile;
  return std::nullopt;
}

Split splitOf(const fs::path& sequence) {
  const std::string name = sequence.filename().string();
  const std::string number = name.substr(name.find('_') + 1);
  if (std::stoi(number) == 1) return Split::kMapping;
  if (std::stoi(number) == 2) return Split::kQuery;
  return Split::kUnassigned;
}

// A sequence's pinhole camera (OpenCV pixels, as the authors' evaluator projects with it) and the
// file and line that give it.
struct RioCamera {
  Intrinsics K;  // width, height 0 when the file does not give them
  fs::path file;
  int line = 0;
};

// The authors' format: one line "seqXX_YY fx fy cx cy" per sequence.
std::map<std::string, RioCamera> readIntrinsicsFile(const fs::path& file) {
  std::map<std::string, RioCamera> cameras;
  for (const auto& line : contentLines(readTextLines(file), true)) {
    const auto tokens = splitWhitespace(line.text);
    if (tokens.size() != 5)
      throwInputError(file.string(), line.number,
                      "expected 'seqXX_YY fx fy cx cy', found " + std::to_string(tokens.size()) + " values");
    RioCamera& camera = cameras[tokens[0]];
    camera.K.fx = parseDouble(tokens[1], file, line.number, "fx");
    camera.K.fy = parseDouble(tokens[2], file, line.number, "fy");
    camera.K.cx = parseDouble(tokens[3], file, line.number, "cx");
    camera.K.cy = parseDouble(tokens[4], file, line.number, "cy");
    if (!(camera.K.fx > 0 && camera.K.fy > 0))
      throwInputError(file.string(), line.number, "focal lengths must be positive");
    camera.file = file;
    camera.line = line.number;
  }
  return cameras;
}

// camera.yaml: a camera_intrinsics block with model: [fx, fy, cx, cy] and, optionally, width:
// and height:. Only that subset of YAML is read.
RioCamera readCamera(const fs::path& file) {
  RioCamera camera;
  camera.file = file;
  bool has_model = false;
  for (const auto& line : contentLines(readTextLines(file), true)) {
    const size_t colon = line.text.find(':');
    if (colon == std::string::npos) continue;
    const auto key_tokens = splitWhitespace(line.text.substr(0, colon));
    if (key_tokens.size() != 1) continue;
    const std::string& key = key_tokens[0];
    std::string value = line.text.substr(colon + 1);
    if (key == "model") {
      const size_t open = value.find('['), close = value.find(']');
      if (open == std::string::npos || close == std::string::npos || close < open)
        throwInputError(file.string(), line.number, "expected model: [fx, fy, cx, cy]");
      std::string list = value.substr(open + 1, close - open - 1);
      std::replace(list.begin(), list.end(), ',', ' ');
      const auto values = parseNumbers({line.number, list}, file);
      if (values.size() != 4)
        throwInputError(file.string(), line.number,
                        "expected model: [fx, fy, cx, cy], found " + std::to_string(values.size()) + " numbers");
      camera.K.fx = values[0];
      camera.K.fy = values[1];
      camera.K.cx = values[2];
      camera.K.cy = values[3];
      camera.line = line.number;
      has_model = true;
    } else if (key == "width" || key == "height") {
      const auto tokens = splitWhitespace(value);
      if (tokens.size() != 1) throwInputError(file.string(), line.number, "expected " + key + ": <pixels>");
      (key == "width" ? camera.K.width : camera.K.height) =
          static_cast<int>(parseInteger(tokens[0], file, line.number, key));
    }
  }
  if (!has_model) throwInputError(file.string(), 0, "no camera_intrinsics model: [fx, fy, cx, cy]");
  if (!(camera.K.fx > 0 && camera.K.fy > 0)) throwInputError(file.string(), camera.line, "focal lengths must be positive");
  return camera;
}


}  // namespace

bool looksLikeRio10(const fs::path& dir) {
  const auto sequences = sequenceFolders(dir);
  if (sequences.empty()) return false;
  return intrinsicsFile(dir) || std::any_of(sequences.begin(), sequences.end(), [](const fs::path& sequence) {
           return fs::is_regular_file(sequence / kCameraFile);
         });
}

Scene readRio10(const fs::path& dir) {
  Scene scene = emptyScene(dir, "rio10", true);
  const std::optional<fs::path> intrinsics_file = intrinsicsFile(dir);
  const auto listed_cameras = intrinsics_file ? readIntrinsicsFile(*intrinsics_file) : std::map<std::string, RioCamera>{};
  for (const fs::path& sequence : sequenceFolders(dir)) {
    std::vector<fs::path> images;
    bool has_poses = false;
    for (const auto& entry : fs::directory_iterator(sequence)) {
      const std::string name = entry.path().filename().string();
      if (endsWith(name, kColourSuffix)) images.push_back(entry.path());
      has_poses = has_poses || endsWith(name, kPoseSuffix);
    }
    if (!has_poses) continue;  // a hidden test sequence: nothing to map or score against
    std::sort(images.begin(), images.end());
    const auto listed = listed_cameras.find(sequence.filename().string());
    const fs::path camera_file = sequence / kCameraFile;
    if (listed == listed_cameras.end() && !fs::exists(camera_file))
      throwInputError(sequence.string(), 0,
                      std::string("no camera: no ") + kCameraFile + " in it, and " +
                          (intrinsics_file ? intrinsics_file->string() + " has no line for it"
                                           : std::string("no ") + kIntrinsicsFile + " in the scene folder or above it"));
    const RioCamera camera = listed != listed_cameras.end() ? listed->second : readCamera(camera_file);
    for (const fs::path& image : images) {
      const std::string name = image.filename().string();
      const std::string stem = name.substr(0, name.size() - std::string(kColourSuffix).size());
      Frame frame;
      frame.image_path = image;
      frame.name = frameName(image, dir);
      frame.intrinsics = camera.K;
      if (camera.K.width > 0 || camera.K.height > 0) {
        requireImageSize(image, camera.K.width, camera.K.height, camera.file.string(), camera.line);
      } else {
        const cv::Size size = readImageSize(image);
        frame.intrinsics.width = size.width;
        frame.intrinsics.height = size.height;
      }
      const fs::path pose_file = sequence / (stem + kPoseSuffix);
      if (!fs::exists(pose_file))
        throwInputError(image.string(), 0, "no pose " + pose_file.filename().string() + " beside it");
      const MatrixFile pose = readMatrixFile(pose_file, 4, 4);
      frame.camera_to_world = validatedPose(pose.values, pose_file, pose.row_lines);
      const fs::path depth = sequence / (stem + kDepthSuffix);
      if (fs::exists(depth)) frame.depth = millimetreDepth(depth);
      frame.split = splitOf(sequence);
      scene.frames.push_back(std::move(frame));
    }
  }
  if (scene.frames.empty()) throwInputError(dir.string(), 0, "no RIO10 sequence with poses (seqXX_YY/frame-*.pose.txt)");
  return scene;
}

std::vector<std::string> writeRio10(const Scene& scene, const fs::path& out) {
  requireNoDistortion(scene, "rio10");
  std::vector<std::string> names;
  const char* sequences[] = {"seq01_01", "seq01_02", "seq01_03"};
  int counters[3] = {0, 0, 0};
  const Intrinsics* camera_of[3] = {nullptr, nullptr, nullptr};
  for (const Frame& frame : scene.frames) {
    const int s = frame.split == Split::kMapping ? 0 : frame.split == Split::kQuery ? 1 : 2;
    // One camera.yaml per sequence: RIO10 has no per-frame intrinsics.
    if (!camera_of[s]) {
      camera_of[s] = &frame.intrinsics;
      const Intrinsics& K = frame.intrinsics;
      writeTextCreatingFolders(out / sequences[s] / kCameraFile,
                               "camera_intrinsics:\n  height: " + std::to_string(K.height) + "\n  width: " +
                                   std::to_string(K.width) + "\n  model: [" + formatNumber(K.fx) + ", " +
                                   formatNumber(K.fy) + ", " + formatNumber(K.cx) + ", " + formatNumber(K.cy) + "]\n");
    } else if (!sameIntrinsics(*camera_of[s], frame.intrinsics)) {
      throwInputError(frame.name, 0,
                      std::string("its intrinsics differ from the rest of ") + sequences[s] +
                          "'s, and RIO10 stores one camera per sequence");
    }
    char stem[32];
    std::snprintf(stem, sizeof(stem), "frame-%06d", counters[s]++);
    const fs::path folder = out / sequences[s];
    copyFrameImage(frame, folder / (std::string(stem) + kColourSuffix), true);
    writeTextCreatingFolders(folder / (std::string(stem) + kPoseSuffix), matrixText(frame.camera_to_world.matrix()));
    if (frame.depth) writeDepthMillimetrePng(frame, folder / (std::string(stem) + kDepthSuffix));
    names.push_back(std::string(sequences[s]) + "/" + stem + kColourSuffix);
  }
  return names;
}

}  // namespace ffloc
