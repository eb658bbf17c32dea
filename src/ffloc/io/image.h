#pragma once

#include <filesystem>
#include <opencv2/core.hpp>

#include "ffloc/geometry/camera.h"

namespace ffloc {

// Reads an image as 8-bit RGB (3 channels, HxW). Throws InputError naming the file when it is
// missing or cannot be decoded.
cv::Mat readImageRgb(const std::filesystem::path& path);

// A decoded image (OpenCV's BGR, 3 channels, any depth) as 8-bit RGB. 16-bit PNGs and TIFFs often
// hold 10 or 12 bits (a machine-vision camera's): keeping their top byte, as OpenCV's 8-bit
// decoding does, left them near black and unlocalizable, so an image of more than 8 bits is
// scaled from the bits its largest value needs; a floating-point one from [0, 1] or its largest value.
cv::Mat rgbFromDecoded(const cv::Mat& bgr);

}  // namespace ffloc
