// The layout ACE, GLACE and DSAC* read (7-Scenes, 12-Scenes, Cambridge and Wayspots as those
// projects prepare them): train/ and test/, each with rgb/, poses/ (4x4 camera-to-world per
// frame), calibration/ (a focal length or a 3x3 K per frame) and optionally depth/.
#include <map>

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

const std::pair<const char*, Split> kSplitFolders[] = {{"train", Split::kMapping}, {"test", Split::kQuery}};

// Files of one folder keyed by the part of their name before the first '.': the tools pair
// rgb/x.color.png with poses/x.pose.txt, and Cambridge's rgb/x.png with poses/x.txt. Hidden
// files (".DS_Store") are not frames. Two files of one stem are refused: an editor's backup
// (x.pose.txt~) took the frame's pose, whichever the folder listed last.
std::map<std::string, fs::path> filesByStem(const fs::path& folder) {
  std::map<std::string, fs::path> files;
  if (!fs::is_directory(folder)) return files;
  for (const auto& entry : fs::directory_iterator(folder)) {
    if (!entry.is_regular_file() || entry.path().filename().string().front() == '.') continue;
    const std::string name = entry.path().filename().string();
    const auto [kept, added] = files.emplace(name.substr(0, name.find('.')), entry.path());
    if (!added) {
      std::string first = kept->second.filename().string(), second = name;
      if (second < first) std::swap(first, second);
      throwInputError(folder.string(), 0,
                      "'" + first + "' and '" + second + "' are both files of frame '" + kept->first +
                          "' (its name up to the first '.'); remove or rename one");
    }
  }
  return files;
}

// A single focal length (principal point at the image centre) or a 3x3 K, both as written.
Intrinsics readCalibration(const fs::path& file, const cv::Size& size) {
  std::vector<double> values;
  int last_line = 0;
  for (const auto& line : contentLines(readTextLines(file), true)) {
    for (double v : parseNumbers(line, file)) values.push_back(v);
    last_line = line.number;
  }
  Intrinsics K;
  K.width = size.width;
  K.height = size.height;
  if (values.size() == 1) {
    K.fx = K.fy = values[0];
    // The image centre in OpenCV pixels (the top-left pixel's centre is (0, 0)).
    K.cx = 0.5 * (size.width - 1);
    K.cy = 0.5 * (size.height - 1);
  } else if (values.size() == 9) {
    if (values[1] != 0 || values[3] != 0 || values[6] != 0 || values[7] != 0 || values[8] != 1)
      throwInputError(file.string(), last_line, "not a pinhole K matrix (expected fx 0 cx / 0 fy cy / 0 0 1)");
    K.fx = values[0];
    K.fy = values[4];
    K.cx = values[2];
    K.cy = values[5];
  } else {
    throwInputError(file.string(), last_line,
                    "expected a focal length or a 3x3 matrix, found " + std::to_string(values.size()) + " numbers");
  }
  if (!(K.fx > 0 && K.fy > 0)) throwInputError(file.string(), last_line, "focal lengths must be positive");
  return K;
}

const fs::path& requireCompanion(const std::map<std::string, fs::path>& files, const std::string& stem,
                                 const fs::path& folder, const fs::path& image) {
  const auto found = files.find(stem);
  if (found == files.end())
    throwInputError(image.string(), 0, "no " + folder.filename().string() + " file " + stem + ".* in " + folder.string());
  return found->second;
}

}  // namespace

bool looksLikeAceLayout(const fs::path& dir) {
  for (const auto& [folder, split] : kSplitFolders)
    if (fs::is_directory(dir / folder / "rgb") && fs::is_directory(dir / folder / "poses")) return true;
  return false;
}

Scene readAceLayout(const fs::path& dir) {
  Scene scene = emptyScene(dir, "ace", true);
  for (const auto& [folder, split] : kSplitFolders) {
    const fs::path root = dir / folder;
    if (!fs::is_directory(root / "rgb")) continue;
    const auto poses = filesByStem(root / "poses");
    const auto calibrations = filesByStem(root / "calibration");
    const auto depths = filesByStem(root / "depth");
    for (const auto& [stem, image] : filesByStem(root / "rgb")) {
      Frame frame;
      frame.image_path = image;
      frame.name = frameName(image, dir);
      const cv::Size size = readImageSize(image);
      frame.intrinsics = readCalibration(requireCompanion(calibrations, stem, root / "calibration", image), size);
      // A copy: bound by reference beside temporary arguments, GCC 13 warns of a dangling one.
      const fs::path pose_file = requireCompanion(poses, stem, root / "poses", image);
      const MatrixFile pose = readMatrixFile(pose_file, 4, 4);
      frame.camera_to_world = validatedPose(pose.values, pose_file, pose.row_lines);
      if (const auto depth = depths.find(stem); depth != depths.end()) frame.depth = millimetreDepth(depth->second);
      frame.split = split;
      scene.frames.push_back(std::move(frame));
    }
  }
  if (scene.frames.empty()) throwInputError(dir.string(), 0, "no images in train/rgb or test/rgb");
  return scene;
}

std::vector<std::string> writeAceLayout(const Scene& scene, const fs::path& out) {
  requireNoDistortion(scene, "ace");
  const auto stems = uniqueFrameStems(scene);
  std::vector<std::string> names;
  for (size_t i = 0; i < scene.frames.size(); ++i) {
    const Frame& frame = scene.frames[i];
    const fs::path root = out / (isQuerySide(frame) ? "test" : "train");
    const std::string& stem = stems[i];
    const fs::path image = root / "rgb" / (stem + ".color" + imageExtension(frame));
    copyFrameImage(frame, image);
    writeTextCreatingFolders(root / "poses" / (stem + ".pose.txt"), matrixText(frame.camera_to_world.matrix()));
    writeTextCreatingFolders(root / "calibration" / (stem + ".calibration.txt"), matrixText(frame.intrinsics.K()));
    if (frame.depth) writeDepthMillimetrePng(frame, root / "depth" / (stem + ".depth.png"));
    names.push_back(frameName(image, out));
  }
  return names;
}

}  // namespace ffloc
