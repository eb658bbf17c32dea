#pragma once

#include <filesystem>
#include <opencv2/core.hpp>

#include "ffloc/geometry/camera.h"

namespace ffloc {

// Reads an image as 8-bit RGB (3 channels, HxW). Throws InputError naming the file when it is
// missing or cannot be decoded.
cv::Mat readImageRgb(const std::filesystem::path& path);

}  // namespace ffloc
