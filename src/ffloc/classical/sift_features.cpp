#include "ffloc/classical/sift_features.h"

#include <algorithm>
#include <cmath>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "ffloc/core/error.h"
#include "ffloc/core/root_sift.h"
#include "ffloc/io/image.h"

namespace ffloc {
namespace {

// OpenCV's first octave is the image doubled: its pixel j samples the original at j / 2 - 1/4,
// while OpenCV reports a keypoint found at j at j / 2 (SiftOptions::correct_upsampling_offset;
// OpenCV's issue 23123). OpenCV 4.8's `enable_precise_upscale`, off by default, removes the offset
// at its source: turning it on would need this off.
constexpr double kUpsamplingOffset = 0.25;

// OpenCV's cap keeps every keypoint tied with the last one it keeps (the orientations of one
// point share its response), so a cap of N could keep several more. The strongest `limit`, the
// first of a tie first.
void keepStrongest(std::vector<cv::KeyPoint>& keypoints, cv::Mat& descriptors, int limit) {
  if (static_cast<int>(keypoints.size()) <= limit) return;
  std::vector<int> order(keypoints.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return keypoints[a].response > keypoints[b].response; });
  order.resize(limit);
  std::sort(order.begin(), order.end());  // in the order OpenCV gave them
  std::vector<cv::KeyPoint> kept;
  cv::Mat kept_descriptors(limit, descriptors.cols, descriptors.type());
  for (int i = 0; i < limit; ++i) {
    kept.push_back(keypoints[order[i]]);
    descriptors.row(order[i]).copyTo(kept_descriptors.row(i));
  }
  keypoints = std::move(kept);
  descriptors = kept_descriptors;
}

}  // namespace

void SiftOptions::check() const {
  if (max_image_size < 16 || max_image_size > kMaxImageSize)
    throw InputError("max_image_size: must be in [16, " + std::to_string(kMaxImageSize) + "] pixels, got " +
                     std::to_string(max_image_size));
  if (max_features <= 0 || max_features > kMaxFeatures)
    throw InputError("max_features: must be in [1, " + std::to_string(kMaxFeatures) + "], got " +
                     std::to_string(max_features));
  if (!(contrast_threshold > 0 && contrast_threshold < 1))
    throw InputError("contrast_threshold: must be in (0, 1), got " + std::to_string(contrast_threshold));
  if (min_features < 0 || min_features > kMaxFeatures)
    throw InputError("min_features: must be in [0, " + std::to_string(kMaxFeatures) + "], got " +
                     std::to_string(min_features));
  if (!(low_contrast_threshold > 0 && low_contrast_threshold <= contrast_threshold))
    throw InputError("low_contrast_threshold: must be in (0, contrast_threshold], got " +
                     std::to_string(low_contrast_threshold));
}

SiftFeatures extractSiftFeatures(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string& source,
                                 const SiftOptions& options) {
  options.check();
  if (rgb.cols != intrinsics.width || rgb.rows != intrinsics.height)
    throw InputError(source + ": image is " + std::to_string(rgb.cols) + "x" + std::to_string(rgb.rows) +
                     " but its intrinsics are for " + std::to_string(intrinsics.width) + "x" +
                     std::to_string(intrinsics.height));
  cv::Mat gray;
  cv::cvtColor(rgb, gray, cv::COLOR_RGB2GRAY);

  SiftFeatures features;
  const int long_side = std::max(gray.cols, gray.rows);
  if (long_side > options.max_image_size) {
    features.working_scale = static_cast<double>(options.max_image_size) / long_side;
    // The size given, not the factor: OpenCV then samples each axis at exactly the ratio of the
    // sizes, the one keypoints are mapped back with below (given the factor, it samples at the
    // factor and rounds the size, up to 0.65 px apart at the edge of a Strecha image). At least
    // one pixel across: a sliver of an image (2100 x 1) has no features, as a tiny one has none.
    const cv::Size working(std::max(1, static_cast<int>(std::lround(gray.cols * features.working_scale))),
                           std::max(1, static_cast<int>(std::lround(gray.rows * features.working_scale))));
    cv::Mat small;
    cv::resize(gray, small, working, 0, 0, cv::INTER_AREA);
    gray = small;
  }

  // Detection runs on the (possibly distorted) image; only keypoint positions are undistorted,
  // which avoids resampling the image and keeps SIFT's sub-pixel localisation intact.
  std::vector<cv::KeyPoint> keypoints;
  cv::SIFT::create(options.max_features, 3, options.contrast_threshold)
      ->detectAndCompute(gray, cv::noArray(), keypoints, features.descriptors);
  const int wanted = std::min(options.min_features, options.max_features);
  int limit = options.max_features;
  if (static_cast<int>(keypoints.size()) < wanted) {
    keypoints.clear();
    cv::SIFT::create(wanted, 3, options.low_contrast_threshold)
        ->detectAndCompute(gray, cv::noArray(), keypoints, features.descriptors);
    limit = wanted;
  }
  keepStrongest(keypoints, features.descriptors, limit);
  if (features.descriptors.empty()) features.descriptors = cv::Mat(0, 128, CV_32F);
  if (features.descriptors.type() != CV_32F) features.descriptors.convertTo(features.descriptors, CV_32F);
  toRootSift(features.descriptors);

  // Working pixel -> original pixel, keeping pixel edges aligned (centres at integers).
  const double sx = static_cast<double>(gray.cols) / rgb.cols, sy = static_cast<double>(gray.rows) / rgb.rows;
  const double offset = options.correct_upsampling_offset ? kUpsamplingOffset : 0.0;
  features.distorted_pixels.resize(keypoints.size());
  for (size_t i = 0; i < keypoints.size(); ++i)
    features.distorted_pixels[i] = {(keypoints[i].pt.x - offset + 0.5) / sx - 0.5,
                                    (keypoints[i].pt.y - offset + 0.5) / sy - 0.5};
  features.pixels = undistortPixels(intrinsics, features.distorted_pixels);
  return features;
}

SiftFeatures extractSiftFeatures(const Frame& frame, const SiftOptions& options) {
  return extractSiftFeatures(readImageRgb(frame.image_path), frame.intrinsics,
                             frame.image_path.string() + " (frame '" + frame.name + "')", options);
}

cv::Mat quantizeDescriptors(const cv::Mat& descriptors) {
  cv::Mat quantized;
  descriptors.convertTo(quantized, CV_8U, 255.0);  // saturating, rounded
  return quantized;
}

cv::Mat dequantizeDescriptors(const cv::Mat& quantized) {
  cv::Mat descriptors;
  quantized.convertTo(descriptors, CV_32F, 1.0 / 255.0);
  return descriptors;
}

}  // namespace ffloc
