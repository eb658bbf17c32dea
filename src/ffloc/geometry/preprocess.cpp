#include "ffloc/geometry/preprocess.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "ffloc/core/error.h"

namespace ffloc {

Eigen::Vector2d PreprocessGeometry::toPreprocessed(const Eigen::Vector2d& p) const {
  const double sx = static_cast<double>(resized_width) / original_width;
  const double sy = static_cast<double>(resized_height) / original_height;
  return {(p.x() + 0.5) * sx - 0.5 - crop_x, (p.y() + 0.5) * sy - 0.5 - crop_y};
}

Eigen::Vector2d PreprocessGeometry::toOriginal(const Eigen::Vector2d& p) const {
  const double sx = static_cast<double>(resized_width) / original_width;
  const double sy = static_cast<double>(resized_height) / original_height;
  return {(p.x() + crop_x + 0.5) / sx - 0.5, (p.y() + crop_y + 0.5) / sy - 0.5};
}

Intrinsics PreprocessGeometry::apply(const Intrinsics& original) const {
  const double sx = static_cast<double>(resized_width) / original_width;
  const double sy = static_cast<double>(resized_height) / original_height;
  return original.scaled(sx, sy, resized_width, resized_height).cropped(crop_x, crop_y, width, height);
}

PreprocessGeometry preprocessGeometry(int width, int height, const PreprocessOptions& options) {
  if (width <= 0 || height <= 0)
    throw InputError("image preprocessing: empty image (" + std::to_string(width) + "x" +
                     std::to_string(height) + ")");
  if (options.long_side < options.patch_size || options.patch_size <= 0)
    throw InputError("image preprocessing: long side " + std::to_string(options.long_side) +
                     " is smaller than the patch size " + std::to_string(options.patch_size));
  PreprocessGeometry g;
  g.original_width = width;
  g.original_height = height;
  const double factor = static_cast<double>(options.long_side) / std::max(width, height);
  g.resized_width = std::max(1, static_cast<int>(std::lround(width * factor)));
  g.resized_height = std::max(1, static_cast<int>(std::lround(height * factor)));

  // DUSt3R crops symmetrically about the integer centre to the largest multiple of the patch
  // that fits; squares become 4:3 unless square_ok.
  const int centre_x = g.resized_width / 2;
  const int centre_y = g.resized_height / 2;
  const int half_patch = options.patch_size / 2;
  int half_w = ((2 * centre_x) / options.patch_size) * half_patch;
  int half_h = ((2 * centre_y) / options.patch_size) * half_patch;
  if (!options.square_ok && g.resized_width == g.resized_height) half_h = 3 * half_w / 4;
  if (half_w <= 0 || half_h <= 0)
    throw InputError("image preprocessing: " + std::to_string(width) + "x" + std::to_string(height) +
                     " is too small for one " + std::to_string(options.patch_size) + "-pixel patch");
  g.crop_x = centre_x - half_w;
  g.crop_y = centre_y - half_h;
  g.width = 2 * half_w;
  g.height = 2 * half_h;
  return g;
}

PreprocessedImage preprocessImage(const cv::Mat& rgb, const Intrinsics& camera, const PreprocessOptions& options) {
  PreprocessedImage out;
  out.geometry = preprocessGeometry(rgb.cols, rgb.rows, options);
  const PreprocessGeometry& g = out.geometry;
  cv::Mat resized;
  const bool shrinking = g.resized_width < rgb.cols;
  cv::resize(rgb, resized, cv::Size(g.resized_width, g.resized_height), 0, 0,
             shrinking ? cv::INTER_AREA : cv::INTER_CUBIC);
  out.rgb = resized(cv::Rect(g.crop_x, g.crop_y, g.width, g.height)).clone();
  Intrinsics sized = camera;
  sized.width = rgb.cols;
  sized.height = rgb.rows;
  out.intrinsics = g.apply(sized);
  return out;
}

cv::Mat1f preprocessDepthNearest(const cv::Mat1f& depth, const PreprocessGeometry& geometry) {
  cv::Mat1f out(geometry.height, geometry.width, 0.0f);
  for (int y = 0; y < geometry.height; ++y) {
    for (int x = 0; x < geometry.width; ++x) {
      const Eigen::Vector2d original = geometry.toOriginal({x, y});
      const long u = std::lround(original.x()), v = std::lround(original.y());
      if (u < 0 || v < 0 || u >= depth.cols || v >= depth.rows) continue;
      const float d = depth(static_cast<int>(v), static_cast<int>(u));
      if (std::isfinite(d) && d > 0) out(y, x) = d;
    }
  }
  return out;
}

}  // namespace ffloc
