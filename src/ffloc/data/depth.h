#pragma once

#include <filesystem>
#include <opencv2/core.hpp>

#include "ffloc/data/scene.h"

namespace ffloc {

// The frame's depth map in scene units (metres for metric scenes): a 16-bit PNG or a 32-bit
// float TIFF, times DepthSource::scale; invalid stored values, NaN and non-positive depths
// become 0. With a separate depth camera (DepthSource::camera) the result is resampled into the
// frame's own pixel grid. Throws InputError (naming the file) when the frame has no depth, the file is
// missing or unreadable, or its size differs from the frame's intrinsics.
cv::Mat1f readDepthMetres(const Frame& frame);

// Writes a depth map as a single-channel 32-bit float TIFF (read back with depth scale 1).
void writeDepth(const cv::Mat1f& depth, const std::filesystem::path& path);

}  // namespace ffloc
