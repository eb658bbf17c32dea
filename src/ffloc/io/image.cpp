#include "ffloc/io/image.h"

#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ffloc/core/error.h"

namespace ffloc {

cv::Mat readImageRgb(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path)) throwInputError(path.string(), 0, "image: file not found");
  cv::Mat bgr = cv::imread(path.string(), cv::IMREAD_COLOR);
  if (bgr.empty()) throwInputError(path.string(), 0, "image: cannot decode (not an image, or corrupt)");
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

}  // namespace ffloc
