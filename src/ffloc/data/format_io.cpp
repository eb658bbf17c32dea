#include "ffloc/data/format_io.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <limits>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>

#include "ffloc/core/error.h"
#include "ffloc/core/number_text.h"
#include "ffloc/core/utf8.h"
#include "ffloc/core/text_file_writer.h"
#include "ffloc/data/depth.h"
#include "ffloc/io/image_format.h"
#include "ffloc/io/image_size.h"

namespace ffloc {

namespace fs = std::filesystem;

Pose cameraToWorldFromQuaternion(const double q[4], const Eigen::Vector3d& t, const fs::path& file, int line) {
  const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (!std::isfinite(norm) || !t.allFinite())
    throwInputError(file.string(), line, "pose has a non-finite value (NaN or inf)");
  if (std::abs(norm - 1.0) > 1e-2)
    throwInputError(file.string(), line,
                    "quaternion (qw qx qy qz) has norm " + formatNumber(norm) + ", expected a unit quaternion");
  return Pose::fromQuaternion(q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm, t).inverse();
}

std::string worldToCameraQuaternionText(const Pose& camera_to_world, const std::string& separator) {
  const Pose world_to_camera = camera_to_world.inverse();
  const Eigen::Quaterniond q = world_to_camera.quaternion();
  const double values[7] = {q.w(), q.x(), q.y(), q.z(), world_to_camera.t.x(), world_to_camera.t.y(),
                            world_to_camera.t.z()};
  std::string text;
  for (int i = 0; i < 7; ++i) text += (i ? separator : "") + formatNumber(values[i]);
  return text;
}

void writeTextCreatingFolders(const fs::path& path, const std::string& text) {
  if (path.has_parent_path()) fs::create_directories(path.parent_path());
  writeTextFile(path, text);
}

std::string matrixText(const Eigen::MatrixXd& matrix) {
  std::string text;
  for (int r = 0; r < matrix.rows(); ++r) {
    for (int c = 0; c < matrix.cols(); ++c) text += (c ? " " : "") + formatNumber(matrix(r, c));
    text += "\n";
  }
  return text;
}

void requireImageSize(const fs::path& image, int width, int height, const std::string& claim_file, int claim_line) {
  if (!fs::is_regular_file(image)) throwInputError(claim_file, claim_line, "image " + image.string() + " not found");
  const cv::Size size = readImageSize(image);
  if (size.width != width || size.height != height)
    throwInputError(claim_file, claim_line,
                    "says the image is " + std::to_string(width) + "x" + std::to_string(height) + " but " +
                        image.string() + " is " + std::to_string(size.width) + "x" + std::to_string(size.height));
}

void requireEmptyOutputFolder(const fs::path& dir) {
  std::error_code error;
  const fs::file_status status = fs::status(dir, error);
  if (status.type() == fs::file_type::not_found) return;
  if (status.type() == fs::file_type::none)
    throwInputError(dir.string(), 0, "cannot examine the output folder: " + error.message());
  if (status.type() != fs::file_type::directory) throwInputError(dir.string(), 0, "output exists and is not a folder");
  const bool empty = fs::is_empty(dir, error);
  if (error) throwInputError(dir.string(), 0, "cannot examine the output folder: " + error.message());
  if (!empty)
    throwInputError(dir.string(), 0, "output folder is not empty (give a new or empty folder, or remove this one)");
}

namespace {

bool isJpeg(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[3] = {};
  in.read(magic, sizeof(magic));
  return startsLikeJpeg(std::string_view(magic, static_cast<size_t>(in.gcount())));
}

void createParent(const fs::path& path) {
  if (path.has_parent_path()) fs::create_directories(path.parent_path());
}

}  // namespace

void copyFrameImage(const Frame& frame, const fs::path& destination, bool as_jpeg) {
  if (!fs::is_regular_file(frame.image_path)) throwInputError(frame.image_path.string(), 0, "image not found");
  createParent(destination);
  if (as_jpeg && !isJpeg(frame.image_path)) {
    requireDecodableImageFile(frame.image_path, "cannot decode image");
    const cv::Mat image = cv::imread(frame.image_path.string(), cv::IMREAD_UNCHANGED);
    if (image.empty()) throwInputError(frame.image_path.string(), 0, "cannot decode image");
    errno = 0;
    if (!cv::imwrite(destination.string(), image, {cv::IMWRITE_JPEG_QUALITY, 95}))
      throwInputError(destination.string(), 0, "cannot write image" + systemErrorSuffix());
    return;
  }
  fs::copy_file(frame.image_path, destination, fs::copy_options::overwrite_existing);
}

void writeDepthMillimetrePng(const Frame& frame, const fs::path& destination) {
  const cv::Mat1f metres = readDepthMetres(frame);
  cv::Mat1w millimetres(metres.size());
  int beyond = 0, nearer = 0;
  float farthest = 0, nearest = std::numeric_limits<float>::infinity();
  for (int y = 0; y < metres.rows; ++y)
    for (int x = 0; x < metres.cols; ++x) {
      const double mm = std::round(metres(y, x) * 1000.0);
      millimetres(y, x) = mm > 0 && mm < 65535 ? static_cast<uint16_t>(mm) : 0;
      if (mm >= 65535 && std::isfinite(metres(y, x))) {
        ++beyond;
        farthest = std::max(farthest, metres(y, x));
      } else if (mm == 0 && metres(y, x) > 0) {
        ++nearer;
        nearest = std::min(nearest, metres(y, x));
      }
    }
  // Written as 0 they would read back as "no depth" without a word: beyond the largest value, or
  // (a scene in small units, found by an outside probe) under half a millimetre.
  const std::string remedy = ", which 16-bit millimetre depth cannot hold: convert to manifest or kapture, which "
                             "store depth as floats";
  if (beyond > 0)
    throwInputError(frame.name, 0,
                    std::to_string(beyond) + " depth pixels lie beyond 65.534 m (up to " + formatSignificant(farthest) +
                        " m)" + remedy);
  if (nearer > 0)
    throwInputError(frame.name, 0,
                    std::to_string(nearer) + " depth pixels lie nearer than 0.5 mm (down to " + formatSignificant(nearest) +
                        " m)" + remedy);
  createParent(destination);
  errno = 0;
  if (!cv::imwrite(destination.string(), millimetres))
    throwInputError(destination.string(), 0, "cannot write depth image" + systemErrorSuffix());
}

void writeDepthRawFloat(const Frame& frame, const fs::path& destination) {
  const cv::Mat1f metres = readDepthMetres(frame);
  createParent(destination);
  errno = 0;
  std::ofstream out(destination, std::ios::binary);
  // x86 and ARM hosts are little-endian, which is what the format asks for.
  for (int y = 0; y < metres.rows; ++y)
    out.write(reinterpret_cast<const char*>(metres[y]), static_cast<std::streamsize>(metres.cols * sizeof(float)));
  // Closed here: what is still buffered is written now, and a failure then would pass unseen.
  out.close();
  if (!out) throwInputError(destination.string(), 0, "cannot write depth file" + systemErrorSuffix());
}

DepthSource millimetreDepth(const fs::path& path) {
  DepthSource depth;  // the defaults: millimetres, 0 and 65535 invalid
  depth.path = path;
  return depth;
}

bool isQuerySide(const Frame& frame) { return frame.split == Split::kQuery; }

namespace {

// The names, each unique, or an InputError naming the two frames that share one.
std::vector<std::string> requireUnique(const Scene& scene, std::vector<std::string> names, const std::string& what) {
  std::map<std::string, std::string> owner;
  for (size_t i = 0; i < names.size(); ++i) {
    const auto [it, inserted] = owner.emplace(names[i], scene.frames[i].name);
    if (!inserted)
      throwInputError(scene.root.string(), 0,
                      "frames '" + it->second + "' and '" + scene.frames[i].name + "' would both be written as " +
                          what + " '" + names[i] + "'");
  }
  return names;
}

}  // namespace

std::vector<std::string> portableFrameNames(const Scene& scene) {
  std::vector<std::string> names;
  for (const Frame& frame : scene.frames) {
    fs::path portable;
    for (const fs::path& part : fs::path(frame.name).lexically_normal())
      if (!(portable.empty() && (part == ".." || part == "."))) portable /= part;
    names.push_back(portable.generic_string());
  }
  return requireUnique(scene, names, "path");
}

std::vector<std::string> uniqueFrameStems(const Scene& scene) {
  std::vector<std::string> stems;
  for (const std::string& name : portableFrameNames(scene)) {
    const fs::path path(name);
    std::string folders = path.parent_path().generic_string();
    // No '.' either: readers pair a frame's files by the name up to the first one, so 'a.1/img'
    // and 'a.2/img' would both be read as frame 'a'.
    for (char& c : folders)
      if (c == '/' || c == '.') c = '_';
    const std::string file = path.filename().string();
    stems.push_back((folders.empty() ? "" : folders + "_") + file.substr(0, file.find('.')));
  }
  return requireUnique(scene, stems, "stem");
}

bool sameIntrinsics(const Intrinsics& a, const Intrinsics& b) {
  return a.width == b.width && a.height == b.height && a.fx == b.fx && a.fy == b.fy && a.cx == b.cx &&
         a.cy == b.cy && a.distortion == b.distortion;
}

void requireNoDistortion(const Scene& scene, const std::string& format) {
  for (const Frame& frame : scene.frames)
    if (frame.intrinsics.hasDistortion())
      throwInputError(frame.name, 0,
                      "has lens distortion, which the " + format +
                          " format cannot store (convert to manifest or kapture, or undistort the images first)");
}

std::string imageExtension(const Frame& frame) {
  return asciiLowercase(frame.image_path.extension().string());
}

bool endsWith(const std::string& text, const std::string& suffix) {
  return text.size() >= suffix.size() && text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace ffloc
