#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "ffloc/geometry/camera.h"

namespace ffloc {

// DUSt3R's inference preprocessing: resize so the long side is `long_side` (area interpolation
// when shrinking, cubic when enlarging; DUSt3R uses PIL's Lanczos, so pixels are close but not
// bit-identical), then centre-crop both sides down to multiples of `patch_size`; a square
// result is cropped to 4:3 unless square_ok.
struct PreprocessOptions {
  int long_side = 512;
  int patch_size = 16;
  bool square_ok = false;
};

// The geometry of one preprocessing, so pixels and intrinsics can be mapped both ways:
// preprocessed pixel p' = original pixel p scaled about pixel edges, minus the crop offset.
struct PreprocessGeometry {
  int original_width = 0, original_height = 0;
  int resized_width = 0, resized_height = 0;
  int crop_x = 0, crop_y = 0;
  int width = 0, height = 0;  // final, multiples of patch_size

  Eigen::Vector2d toPreprocessed(const Eigen::Vector2d& original_pixel) const;
  Eigen::Vector2d toOriginal(const Eigen::Vector2d& preprocessed_pixel) const;
  Intrinsics apply(const Intrinsics& original) const;
};

PreprocessGeometry preprocessGeometry(int width, int height, const PreprocessOptions& options = {});

struct PreprocessedImage {
  cv::Mat rgb;  // uint8 HxWx3, H and W multiples of the patch size
  Intrinsics intrinsics;
  PreprocessGeometry geometry;
};

// `camera` must describe `rgb` without distortion (undistort first where a dataset has it).
PreprocessedImage preprocessImage(const cv::Mat& rgb, const Intrinsics& camera,
                                  const PreprocessOptions& options = {});

// Nearest-neighbour resampling of a depth map (in the original image grid) into the
// preprocessed image grid; 0 (and non-finite or non-positive depth) becomes invalid, 0.
cv::Mat1f preprocessDepthNearest(const cv::Mat1f& depth, const PreprocessGeometry& geometry);

}  // namespace ffloc
