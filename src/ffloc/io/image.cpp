#include "ffloc/io/image.h"

#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ffloc/core/error.h"
#include "ffloc/io/image_format.h"
#include "ffloc/io/image_size.h"
#include "ffloc/io/input_file.h"

namespace ffloc {

cv::Mat readImageRgb(const std::filesystem::path& path) {
  requireRegularFile(path, "image: file");
  requireDecodableImageFile(path, "image: cannot decode");
  cv::Mat bgr;
  try {
    bgr = cv::imread(path.string(), cv::IMREAD_COLOR | cv::IMREAD_ANYDEPTH);
  } catch (const cv::Exception& error) {
    // OpenCV refuses some headers (a size beyond its limits) by throwing rather than failing,
    // with a message that names its own assertion; the header tells the user what was wrong.
    if (const std::optional<cv::Size> size = fileFrameSize(path)) {
      throwInputError(path.string(), 0,
                      "image: " + std::to_string(size->width) + " x " + std::to_string(size->height) +
                          " pixels, more than the decoder accepts (OPENCV_IO_MAX_IMAGE_PIXELS)");
    }
    throwInputError(path.string(), 0, std::string("image: cannot decode: ") + error.err);
  }
  if (bgr.empty()) throwInputError(path.string(), 0, "image: cannot decode (not an image, or corrupt)");
  return rgbFromDecoded(bgr);
}

cv::Mat rgbFromDecoded(const cv::Mat& bgr) {
  cv::Mat eight_bits = bgr;
  if (bgr.depth() != CV_8U) {
    double largest = 0;
    cv::minMaxLoc(bgr.reshape(1), nullptr, &largest);
    int bits = 8;
    while (bits < 32 && largest >= std::ldexp(1.0, bits)) ++bits;
    const bool floating = bgr.depth() == CV_32F || bgr.depth() == CV_64F;
    const double scale = floating ? (largest > 1 ? 255.0 / largest : 255.0) : std::ldexp(1.0, 8 - bits);
    bgr.convertTo(eight_bits, CV_8U, scale);
  }
  cv::Mat rgb;
  cv::cvtColor(eight_bits, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

}  // namespace ffloc
