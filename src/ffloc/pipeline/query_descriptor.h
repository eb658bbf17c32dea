#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ffloc/model/fastforward_model.h"
#include "ffloc/retrieval/global_descriptor.h"

namespace ffloc {

// The global descriptor of an encoded image (batch 1): the pooling the mapper stores per mapping
// image and the localizer ranks them with.
std::vector<float> encodingDescriptor(const Dust3rEncoding& encoding, const GlobalDescriptorOptions& options = {});

// A query's tokens with the localizer's own preparation (as queryDescriptor below).
Dust3rEncoding queryEncoding(const FastForwardModel& model, const cv::Mat& rgb, const Intrinsics& intrinsics,
                             const std::string& name, int long_side = 0);

// A query's global descriptor with the localizer's own preparation (undistortion, resize, crop at
// `long_side`, 0: the model's input size) and encoder pass, without the decoder: what retrieval
// alone needs. `long_side` and `options` must match the map's (LocalizeOptions::long_side and
// ::descriptor). InputError naming `name` for an empty image or intrinsics that do not fit it.
std::vector<float> queryDescriptor(const FastForwardModel& model, const cv::Mat& rgb, const Intrinsics& intrinsics,
                                   const std::string& name, int long_side = 0,
                                   const GlobalDescriptorOptions& options = {});

}  // namespace ffloc
