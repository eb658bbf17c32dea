// Map-free relocalization benchmark (Niantic; Wayspots ships in the same layout): one scene per
// folder, seq0/ (the mapping scan) and seq1/ (the queries), intrinsics.txt and poses.txt listing
// every image by its path relative to the scene.
#include <map>

#include "ffloc/core/error.h"
#include "ffloc/data/dataset_writers.h"
#include "ffloc/data/format_io.h"
#include "ffloc/data/readers.h"
#include "ffloc/data/text_file.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

constexpr const char* kIntrinsicsFile = "intrinsics.txt";
constexpr const char* kPosesFile = "poses.txt";
// Depth maps beside a frame are named <frame stem>.<source>.png; this is what the writer uses.
constexpr const char* kWrittenDepthSuffix = ".depth.png";

struct PoseLine {
  Pose camera_to_world;
  int line = 0;
};

std::map<std::string, PoseLine> readPoses(const fs::path& file) {
  std::map<std::string, PoseLine> poses;
  for (const auto& line : contentLines(readTextLines(file), true)) {
    const auto tokens = splitWhitespace(line.text);
    if (tokens.size() != 8) throwInputError(file.string(), line.number, "expected 'image_path qw qx qy qz tx ty tz'");
    double q[4];
    const char* q_names[] = {"qw", "qx", "qy", "qz"};
    for (int k = 0; k < 4; ++k) q[k] = parseDouble(tokens[1 + k], file, line.number, q_names[k]);
    const Eigen::Vector3d t(parseDouble(tokens[5], file, line.number, "tx"), parseDouble(tokens[6], file, line.number, "ty"),
                            parseDouble(tokens[7], file, line.number, "tz"));
    // poses.txt holds world-to-camera transforms.
    const PoseLine pose{cameraToWorldFromQuaternion(q, t, file, line.number), line.number};
    if (!poses.emplace(tokens[0], pose).second)
      throwInputError(file.string(), line.number, "second pose for '" + tokens[0] + "'");
  }
  return poses;
}

Split splitOf(const std::string& image_path) {
  const std::string sequence = fs::path(image_path).begin()->string();
  if (sequence == "seq0") return Split::kMapping;
  if (sequence == "seq1") return Split::kQuery;
  return Split::kUnassigned;
}

// The first <stem>.<source>.png beside the image, in name order (map-free ships depth from
// several sources under different suffixes).
std::optional<fs::path> depthBeside(const fs::path& image) {
  const std::string prefix = image.stem().string() + ".";
  std::optional<fs::path> found;
  for (const auto& entry : fs::directory_iterator(image.parent_path())) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) != 0 || entry.path().extension() != ".png" || entry.path() == image) continue;
    if (!found || entry.path() < *found) found = entry.path();
  }
  return found;
}

}  // namespace

bool looksLikeMapFree(const fs::path& dir) {
  return fs::is_regular_file(dir / kIntrinsicsFile) && fs::is_directory(dir / "seq0");
}

Scene readMapFree(const fs::path& dir) {
  Scene scene = emptyScene(dir, "mapfree", true);
  const fs::path intrinsics_file = dir / kIntrinsicsFile;
  const auto poses = readPoses(dir / kPosesFile);
  std::map<std::string, int> listed;
  for (const auto& line : contentLines(readTextLines(intrinsics_file), true)) {
    const auto tokens = splitWhitespace(line.text);
    if (tokens.size() != 7)
      throwInputError(intrinsics_file.string(), line.number, "expected 'image_path fx fy cx cy width height'");
    const std::string& image = tokens[0];
    if (!listed.emplace(image, line.number).second)
      throwInputError(intrinsics_file.string(), line.number, "second entry for '" + image + "'");
    Frame frame;
    Intrinsics& K = frame.intrinsics;
    K.fx = parseDouble(tokens[1], intrinsics_file, line.number, "fx");
    K.fy = parseDouble(tokens[2], intrinsics_file, line.number, "fy");
    K.cx = parseDouble(tokens[3], intrinsics_file, line.number, "cx");
    K.cy = parseDouble(tokens[4], intrinsics_file, line.number, "cy");
    K.width = static_cast<int>(parseInteger(tokens[5], intrinsics_file, line.number, "width"));
    K.height = static_cast<int>(parseInteger(tokens[6], intrinsics_file, line.number, "height"));
    if (!K.isValid())
      throwInputError(intrinsics_file.string(), line.number, "invalid intrinsics (need positive focal lengths and size)");
    frame.image_path = (dir / image).lexically_normal();
    requireImageSize(frame.image_path, K.width, K.height, intrinsics_file.string(), line.number);
    frame.name = frameName(frame.image_path, dir);
    const auto pose = poses.find(image);
    if (pose == poses.end())
      throwInputError(intrinsics_file.string(), line.number, "no pose for '" + image + "' in " + (dir / kPosesFile).string());
    frame.camera_to_world = pose->second.camera_to_world;
    if (const auto depth = depthBeside(frame.image_path)) frame.depth = millimetreDepth(*depth);
    frame.split = splitOf(image);
    scene.frames.push_back(std::move(frame));
  }
  for (const auto& [image, pose] : poses)
    if (!listed.count(image))
      throwInputError((dir / kPosesFile).string(), pose.line, "'" + image + "' is not listed in " + kIntrinsicsFile);
  return scene;
}

std::vector<std::string> writeMapFree(const Scene& scene, const fs::path& out) {
  requireNoDistortion(scene, "mapfree");
  std::string intrinsics, poses;
  std::vector<std::string> names;
  int counters[2] = {0, 0};
  // The benchmark's world is its reference image, seq0/frame_00000 (the first mapping frame):
  // written in the source's world, its poses were misread by map-free's own tools.
  Pose to_reference = Pose::identity();
  for (const Frame& frame : scene.frames)
    if (!isQuerySide(frame)) {
      to_reference = frame.camera_to_world.inverse();
      break;
    }
  for (const Frame& frame : scene.frames) {
    const int sequence = isQuerySide(frame) ? 1 : 0;
    char stem[32];
    std::snprintf(stem, sizeof(stem), "frame_%05d", counters[sequence]++);
    const std::string image = "seq" + std::to_string(sequence) + "/" + stem + imageExtension(frame);
    copyFrameImage(frame, out / image);
    if (frame.depth)
      writeDepthMillimetrePng(frame, out / ("seq" + std::to_string(sequence) + "/" + stem + kWrittenDepthSuffix));
    const Intrinsics& K = frame.intrinsics;
    intrinsics += image + " " + formatNumber(K.fx) + " " + formatNumber(K.fy) + " " + formatNumber(K.cx) + " " +
                  formatNumber(K.cy) + " " + std::to_string(K.width) + " " + std::to_string(K.height) + "\n";
    poses += image + " " + worldToCameraQuaternionText(to_reference * frame.camera_to_world, " ") + "\n";
    names.push_back(image);
  }
  writeTextCreatingFolders(out / kIntrinsicsFile, intrinsics);
  writeTextCreatingFolders(out / kPosesFile, poses);
  return names;
}

}  // namespace ffloc
