#include "ffloc/data/depth.h"

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <vector>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ffloc/core/error.h"
#include "ffloc/data/pose_check.h"
#include "ffloc/io/image_format.h"
#include "ffloc/io/input_file.h"

namespace ffloc {
namespace {

// z-depth is the same for two cameras that share a pose, so registering depth to colour is a
// resampling: each colour pixel looks up the depth pixel on its ray (nearest, so that no depth is
// invented across an edge).
cv::Mat1f toColourGrid(const cv::Mat1f& depth, const Intrinsics& depth_camera, const Intrinsics& colour) {
  const Intrinsics pinhole = colour.undistorted();
  std::vector<Eigen::Vector2d> pixels;
  pixels.reserve(static_cast<size_t>(colour.width) * colour.height);
  for (int y = 0; y < colour.height; ++y)
    for (int x = 0; x < colour.width; ++x) pixels.emplace_back(x, y);
  if (!colour.distortion.empty()) pixels = undistortPixels(colour, pixels);
  cv::Mat1f map_x(colour.height, colour.width), map_y(colour.height, colour.width);
  for (int y = 0, i = 0; y < colour.height; ++y)
    for (int x = 0; x < colour.width; ++x, ++i) {
      const double rx = (pixels[i].x() - pinhole.cx) / pinhole.fx, ry = (pixels[i].y() - pinhole.cy) / pinhole.fy;
      map_x(y, x) = static_cast<float>(depth_camera.fx * rx + depth_camera.cx);
      map_y(y, x) = static_cast<float>(depth_camera.fy * ry + depth_camera.cy);
    }
  cv::Mat1f registered;
  cv::remap(depth, registered, map_x, map_y, cv::INTER_NEAREST, cv::BORDER_CONSTANT, 0.0);
  return registered;
}

// kapture's .depth: raw little-endian float32, row-major, the frame's width x height.
cv::Mat readRawFloatDepth(const std::filesystem::path& path, const Intrinsics& camera) {
  const auto bytes = std::filesystem::file_size(path);
  const auto expected = static_cast<std::uintmax_t>(camera.width) * camera.height * sizeof(float);
  if (bytes != expected)
    throwInputError(path.string(), 0,
                    "raw depth file has " + std::to_string(bytes) + " bytes but the frame's image is " +
                        std::to_string(camera.width) + "x" + std::to_string(camera.height) + " (expected " +
                        std::to_string(expected) + ")");
  cv::Mat1f depth(camera.height, camera.width);
  std::ifstream in(path, std::ios::binary);
  in.read(reinterpret_cast<char*>(depth.data), static_cast<std::streamsize>(expected));
  if (!in) throwInputError(path.string(), 0, "cannot read depth file");
  return depth;
}

}  // namespace

cv::Mat1f readDepthMetres(const Frame& frame) {
  if (!frame.depth) throwInputError(frame.name, 0, "frame has no depth map");
  const DepthSource& source = *frame.depth;
  const std::string file = source.path.string();
  requireRegularFile(source.path, "depth file");
  const Intrinsics& camera = source.camera ? *source.camera : frame.intrinsics;
  const bool raw_floats = source.path.extension() == ".depth";
  if (!raw_floats) requireDecodableImageFile(source.path, "cannot decode depth image");
  cv::Mat stored;
  try {
    // ANYCOLOR keeps a colour image's channels, for the test below: IMREAD_ANYDEPTH alone made
    // them one grey channel.
    stored = raw_floats ? readRawFloatDepth(source.path, camera)
                        : cv::imread(file, cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR);
  } catch (const cv::Exception& error) {
    // OpenCV refuses some headers (a size beyond its limits) by throwing rather than failing.
    throwInputError(file, 0, std::string("cannot decode depth image: ") + error.err);
  }
  if (stored.empty()) throwInputError(file, 0, "cannot decode depth image");
  // Bit depth first: a palette PNG decodes to three 8-bit channels, and its fault is the 8 bits.
  if (stored.depth() == CV_8U || stored.depth() == CV_8S)
    throwInputError(file, 0, "depth image is 8-bit; expected a 16-bit PNG or a 32-bit float TIFF");
  // The decoder gives grey with alpha, or colour with alpha, as three channels.
  if (stored.channels() != 1)
    throwInputError(file, 0, "depth image has colour or alpha channels (decoded to " + std::to_string(stored.channels()) +
                                 " channels; grey with alpha decodes to 3 too); expected one grey channel");
  if (stored.cols != camera.width || stored.rows != camera.height)
    throwInputError(file, 0,
                    "depth image is " + std::to_string(stored.cols) + "x" + std::to_string(stored.rows) + " but " +
                        (source.camera ? "its depth camera is " : "the frame's image is ") +
                        std::to_string(camera.width) + "x" + std::to_string(camera.height));

  // A depth beyond any scene (a depth_scale of 1e300) is no measurement; as a float it would
  // overflow, which C++ leaves undefined.
  const auto metres = [&source](double v) {
    bool invalid = !std::isfinite(v) || v <= 0 || !(v * source.scale <= kMaxCameraDistance);
    for (double bad : source.invalid_values) invalid = invalid || v == bad;
    return invalid ? 0.0f : static_cast<float>(v * source.scale);
  };
  cv::Mat1f depth(stored.size());
  if (stored.depth() == CV_16U) {
    // 16-bit PNGs (7-Scenes, TUM, phone depth) take one table of all 65536 stored values: the
    // per-pixel test and conversion in double took 6 % of the time of mapping such frames.
    std::vector<float> table(65536);
    for (size_t v = 0; v < table.size(); ++v) table[v] = metres(static_cast<double>(v));
    for (int y = 0; y < stored.rows; ++y) {
      const uint16_t* in = stored.ptr<uint16_t>(y);
      float* out = depth[y];
      for (int x = 0; x < stored.cols; ++x) out[x] = table[in[x]];
    }
  } else {
    cv::Mat1d values;
    stored.convertTo(values, CV_64F);
    for (int y = 0; y < values.rows; ++y) {
      const double* in = values[y];
      float* out = depth[y];
      for (int x = 0; x < values.cols; ++x) out[x] = metres(in[x]);
    }
  }
  return source.camera ? toColourGrid(depth, *source.camera, frame.intrinsics) : depth;
}

void writeDepth(const cv::Mat1f& depth, const std::filesystem::path& path) {
  const std::string extension = path.extension().string();
  if (extension != ".tif" && extension != ".tiff")
    throwInputError(path.string(), 0, "depth maps are written as float TIFF; use a .tif or .tiff name");
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
  errno = 0;
  if (!cv::imwrite(path.string(), depth)) throwInputError(path.string(), 0, "cannot write depth image" + systemErrorSuffix());
}

}  // namespace ffloc
