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
    bgr = cv::imread(path.string(), cv::IMREAD_COLOR);
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
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

}  // namespace ffloc
