#pragma once

#include <ATen/core/Tensor.h>
#include <opencv2/core.hpp>

namespace ffloc {

// DUSt3R's input normalisation: uint8 RGB (H, W, 3) -> float32 (1, 3, H, W) in [-1, 1] as
// (u8 / 255 - 0.5) / 0.5, computed with the same float32 ops as torchvision so it is
// bit-identical to the reference.
at::Tensor normalizedImageTensor(const at::Tensor& rgb_uint8_hwc);

// Same from an 8-bit 3-channel RGB cv::Mat (copied). InputError for any other type.
at::Tensor normalizedImageTensor(const cv::Mat& rgb);

}  // namespace ffloc
