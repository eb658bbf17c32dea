#pragma once

#include <ATen/core/Tensor.h>

#include <string>

#include "ffloc/geometry/preprocess.h"
#include "ffloc/io/image.h"
#include "ffloc/model/fastforward_model.h"

namespace ffloc {

// An image ready for the network: undistorted when its camera has distortion, then DUSt3R's
// resize and crop. `camera` is the pinhole camera of the undistorted, full-size image: the grid
// that query pixels are reported in (PreprocessGeometry::toOriginal maps to it).
struct PreparedImage {
  PreprocessedImage preprocessed;
  Intrinsics camera;
};

// InputError naming `name` when the image size disagrees with the intrinsics' width/height (when
// those are set) or the intrinsics are not a valid pinhole camera.
PreparedImage prepareImage(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string& name,
                           const PreprocessOptions& options);

// The encoder's tokens of a prepared image (batch 1).
Dust3rEncoding encodeImage(const FastForwardModel& model, const PreparedImage& image);

// Preprocessing that matches the model's patch size; the long side is DUSt3R's 512 unless told.
// long_side <= 0: the model's input_long_side.
PreprocessOptions preprocessOptionsFor(const FastForwardModel& model, int long_side = 0);

}  // namespace ffloc
