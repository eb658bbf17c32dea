#include <algorithm>
#include <cmath>

#include "ffloc/core/error.h"
#include "ffloc/data/format_io.h"
#include "ffloc/data/pose_check.h"
#include "ffloc/data/readers.h"
#include "ffloc/data/text_file.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

constexpr const char* kCameraFolder = "gt_dense_cameras";
constexpr const char* kCameraSuffix = ".camera";
// OpenCV reads no image with a side beyond this (CV_IO_MAX_IMAGE_WIDTH).
constexpr double kMaxImageSide = 1 << 20;

std::vector<fs::path> cameraFiles(const fs::path& dir) {
  std::vector<fs::path> files;
  if (!fs::is_directory(dir / kCameraFolder)) return files;
  for (const auto& entry : fs::directory_iterator(dir / kCameraFolder))
    if (entry.path().extension() == kCameraSuffix) files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  return files;
}

// K (3 lines), radial distortion k1 k2 k3, R camera-to-world (3 lines), centre C, "w h" of `image`.
Frame readCameraFile(const fs::path& file, const fs::path& image) {
  const auto lines = contentLines(readTextLines(file), false);
  if (lines.size() != 9)
    throwInputError(file.string(), lines.empty() ? 0 : lines.back().number,
                    "expected 9 non-empty lines (K, distortion, R, C, size), found " + std::to_string(lines.size()));
  const int expected_counts[9] = {3, 3, 3, 3, 3, 3, 3, 3, 2};
  std::vector<std::vector<double>> rows;
  for (int r = 0; r < 9; ++r) {
    rows.push_back(parseNumbers(lines[r], file));
    if (static_cast<int>(rows[r].size()) != expected_counts[r])
      throwInputError(file.string(), lines[r].number,
                      "expected " + std::to_string(expected_counts[r]) + " numbers, found " + std::to_string(rows[r].size()));
    for (double v : rows[r])
      if (!std::isfinite(v)) throwInputError(file.string(), lines[r].number, "non-finite value (NaN or inf)");
  }
  Frame frame;
  Intrinsics& K = frame.intrinsics;
  if (rows[0][1] != 0 || rows[1][0] != 0 || rows[2][0] != 0 || rows[2][1] != 0 || rows[2][2] != 1)
    throwInputError(file.string(), lines[0].number, "K is not a pinhole matrix (fx 0 cx / 0 fy cy / 0 0 1)");
  K.fx = rows[0][0];
  K.cx = rows[0][2];
  K.fy = rows[1][1];
  K.cy = rows[1][2];
  // Here, not with the image size on line 9, to which a negative focal length was blamed.
  for (const int row : {0, 1})
    if (!(rows[row][row] > 0)) throwInputError(file.string(), lines[row].number, "the focal length must be positive");
  const std::vector<double>& radial = rows[3];
  if (radial[0] != 0 || radial[1] != 0 || radial[2] != 0) K.distortion = {radial[0], radial[1], 0, 0, radial[2]};
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r) R.row(r) = Eigen::RowVector3d(rows[4 + r][0], rows[4 + r][1], rows[4 + r][2]);
  frame.camera_to_world.R = validatedRotation(R, file, lines[4].number);
  frame.camera_to_world.t = Eigen::Vector3d(rows[7][0], rows[7][1], rows[7][2]);
  const std::string centre = cameraCentreProblem(frame.camera_to_world.t);
  if (!centre.empty()) throwInputError(file.string(), lines[7].number, centre);
  // Checked before the conversion to int, which is undefined for values an int cannot hold.
  for (const double side : rows[8])
    if (!(side >= 1 && side <= kMaxImageSide) || side != std::floor(side))
      throwInputError(file.string(), lines[8].number,
                      "image size must be two whole numbers in [1, " + std::to_string(kMaxImageSide) + "]");
  K.width = static_cast<int>(rows[8][0]);
  K.height = static_cast<int>(rows[8][1]);
  requireLensDistortion(K, file, lines[3].number);
  requireImageSize(image, K.width, K.height, file.string(), lines[8].number);
  frame.image_path = image;
  return frame;
}

}  // namespace

bool looksLikeStrecha(const fs::path& dir) { return !cameraFiles(dir).empty(); }

Scene readStrecha(const fs::path& dir) {
  Scene scene = emptyScene(dir, "strecha", true);
  const auto files = cameraFiles(dir);
  if (files.empty()) throwInputError((dir / kCameraFolder).string(), 0, "no .camera files");
  for (const auto& file : files) {
    // "0000.jpg.camera" -> "0000.jpg"
    Frame frame = readCameraFile(file, dir / "images" / file.stem());
    frame.name = frameName(frame.image_path, dir);
    scene.frames.push_back(std::move(frame));
  }
  return scene;
}

}  // namespace ffloc
