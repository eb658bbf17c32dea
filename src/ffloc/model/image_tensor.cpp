#include "ffloc/model/image_tensor.h"

#include <ATen/ops/empty.h>

#include <cstring>

#include "ffloc/core/error.h"

namespace ffloc {

at::Tensor normalizedImageTensor(const at::Tensor& rgb_uint8_hwc) {
  if (rgb_uint8_hwc.dim() != 3 || rgb_uint8_hwc.size(2) != 3 || rgb_uint8_hwc.scalar_type() != at::kByte) {
    throwInputError("image tensor", 0, "expected uint8 (H, W, 3), got " + rgb_uint8_hwc.toString() +
                                           " of " + std::to_string(rgb_uint8_hwc.dim()) + " dims");
  }
  const at::Tensor chw = rgb_uint8_hwc.permute({2, 0, 1}).to(at::kFloat).div(255);
  return chw.sub(0.5).div(0.5).unsqueeze(0).contiguous();
}

at::Tensor normalizedImageTensor(const cv::Mat& rgb) {
  if (rgb.type() != CV_8UC3 || rgb.empty()) {
    throwInputError("image", 0, "expected a non-empty 8-bit 3-channel RGB image");
  }
  at::Tensor hwc = at::empty({rgb.rows, rgb.cols, 3}, at::TensorOptions().dtype(at::kByte));
  uint8_t* out = hwc.data_ptr<uint8_t>();
  const size_t row_bytes = static_cast<size_t>(rgb.cols) * 3;
  for (int r = 0; r < rgb.rows; ++r) std::memcpy(out + r * row_bytes, rgb.ptr<uint8_t>(r), row_bytes);
  return normalizedImageTensor(hwc);
}

}  // namespace ffloc
