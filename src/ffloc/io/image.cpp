#include "ffloc/io/image.h"

#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ffloc/core/error.h"
#include "ffloc/io/input_file.h"

namespace ffloc {

cv::Mat readImageRgb(const std::filesystem::path& path) {
  requireRegularFile(path, "image: file");
  cv::Mat bgr;
  try {
    bgr = cv::imread(path.string(), cv::IMREAD_COLOR);
  } catch (const cv::Exception& error) {
    // OpenCV refuses some headers (a size beyond its limits) by throwing rather than failing.
    throwInputError(path.string(), 0, std::string("image: cannot decode: ") + error.err);
  }
  if (bgr.empty()) throwInputError(path.string(), 0, "image: cannot decode (not an image, or corrupt)");
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

}  // namespace ffloc
