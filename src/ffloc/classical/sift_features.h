#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

#include "ffloc/data/scene.h"
#include "ffloc/geometry/camera.h"

namespace ffloc {

// How SIFT features are detected. A map records the options it was built with, and its queries
// are described with the same ones.
struct SiftOptions {
  // Beyond any camera and any image's keypoints; a map file holds no larger value.
  static constexpr int kMaxImageSize = 1 << 20;
  static constexpr int kMaxFeatures = 1 << 24;

  // Images are shrunk (never enlarged) so the long side is at most this many pixels before
  // detection; keypoints are mapped back to the original undistorted grid. On Strecha's 3072 px
  // images 1024 px and 4000 features localise as well as 1600 px and 8000 (1.9 mm against
  // 1.7 mm median) at a quarter of the matching time (docs/classical.md).
  int max_image_size = 1024;
  int max_features = 4000;            // per image, strongest first, never more
  double contrast_threshold = 0.02;   // SIFT's; lower than OpenCV's 0.04 to keep weak indoor texture
  // An image with fewer keypoints than this at contrast_threshold (a small image, weak texture)
  // is described again down to low_contrast_threshold, keeping the strongest min_features: on
  // the 256 x 192 synthetic scenes 14 % more queries land within (25 cm, 5 deg), while images
  // that already have them (redkitchen's 640 x 480, Strecha) are described exactly as before,
  // where a lower threshold everywhere cost accuracy and doubled redkitchen's query time
  // (docs/classical.md). 0 turns it off (maps written before it existed).
  int min_features = 1000;
  double low_contrast_threshold = 0.005;
  // OpenCV 4.6 detects on the image doubled by bilinear resampling and halves the positions back
  // without the half pixel that resampling moved them: every keypoint comes out a quarter of a
  // working pixel right of and below the blob it marks (0.75 px on a Strecha image). Corrected,
  // unless a map was written before the correction existed: its queries keep the offset its
  // images have.
  bool correct_upsampling_offset = true;

  // InputError naming the field for a value out of range.
  void check() const;
};

// Features of one image. Pixels are in the original image's undistorted pixel grid.
struct SiftFeatures {
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector2d> distorted_pixels;  // the same keypoints in the image as stored
  cv::Mat descriptors;        // RootSIFT, CV_32F, one row per keypoint, unit L2 norm
  double working_scale = 1;   // working-resolution pixels per original pixel
};

// Detects SIFT on `rgb` (shrunk to the working resolution) and maps the keypoints to
// `intrinsics.undistorted()` pixels. InputError naming `source` when the image size disagrees
// with the intrinsics.
SiftFeatures extractSiftFeatures(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string& source,
                                 const SiftOptions& options = {});
// The same for a frame's image file.
SiftFeatures extractSiftFeatures(const Frame& frame, const SiftOptions& options = {});

// RootSIFT descriptors stored as bytes: each component (in [0, 1]) times 255, rounded: a map four
// times smaller, and 684 of 702 ratio-test matches the same on decoded values (docs/classical.md).
cv::Mat quantizeDescriptors(const cv::Mat& descriptors);    // CV_32F -> CV_8U
cv::Mat dequantizeDescriptors(const cv::Mat& quantized);    // CV_8U -> CV_32F

}  // namespace ffloc
