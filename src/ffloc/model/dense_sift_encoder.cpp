#include "ffloc/model/dense_sift_encoder.h"

#include <ATen/TensorOperators.h>
#include <ATen/ops/empty.h>

#include <cmath>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "ffloc/core/error.h"
#include "ffloc/core/root_sift.h"

namespace ffloc {

void DenseSiftConfig::validate(const std::string& origin) const {
  if (window_sizes.empty()) throwInputError(origin, 0, "field 'window_sizes': at least one window is needed");
  for (double size : window_sizes) {
    if (!(size >= 6 && size <= 1024)) {
      throwInputError(origin, 0, "field 'window_sizes': each must be in [6, 1024] pixels, got " + std::to_string(size));
    }
  }
}

namespace {

// (3, H, W) float in [-1, 1] back to the 8-bit grey image SIFT works on.
cv::Mat greyImage(const at::Tensor& chw) {
  const at::Tensor hwc = ((chw.to(at::kFloat) * 0.5 + 0.5) * 255.0).clamp(0, 255).round().to(at::kByte).permute({1, 2, 0}).contiguous();
  const cv::Mat rgb(static_cast<int>(hwc.size(0)), static_cast<int>(hwc.size(1)), CV_8UC3, hwc.data_ptr());
  cv::Mat grey;
  cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
  return grey;
}

}  // namespace

Dust3rEncoding denseSiftEncode(const at::Tensor& images, int64_t patch_size, const DenseSiftConfig& config) {
  config.validate();
  if (images.dim() != 4 || images.size(1) != 3) throwInputError("dense-sift encoder", 0, "expected (B, 3, H, W) images");
  const int64_t batch = images.size(0), height = images.size(2), width = images.size(3);
  if (patch_size <= 0 || height % patch_size != 0 || width % patch_size != 0) {
    throwInputError("dense-sift encoder", 0, "image of " + std::to_string(width) + "x" + std::to_string(height) +
                                                 " px is not a whole number of " + std::to_string(patch_size) +
                                                 " px patches");
  }
  const int64_t rows = height / patch_size, cols = width / patch_size, tokens = rows * cols;
  const at::Tensor cpu_images = images.detach().cpu();
  at::Tensor out = at::empty({batch, tokens, config.tokenDim()}, at::TensorOptions().dtype(at::kFloat));
  const cv::Ptr<cv::SIFT> sift = cv::SIFT::create();
  const float window_share = static_cast<float>(1.0 / std::sqrt(static_cast<double>(config.window_sizes.size())));
  for (int64_t b = 0; b < batch; ++b) {
    const cv::Mat grey = greyImage(cpu_images[b]);
    cv::Mat token_rows(static_cast<int>(tokens), static_cast<int>(config.tokenDim()), CV_32F,
                       out[b].data_ptr<float>());
    // Every window's keypoints in one call: SIFT builds its scale pyramid once per call.
    const size_t windows = config.window_sizes.size();
    std::vector<cv::KeyPoint> keypoints;
    keypoints.reserve(static_cast<size_t>(tokens) * windows);
    for (size_t w = 0; w < windows; ++w) {
      for (int64_t r = 0; r < rows; ++r) {
        for (int64_t c = 0; c < cols; ++c) {
          const float x = static_cast<float>((c + 0.5) * patch_size - 0.5), y = static_cast<float>((r + 0.5) * patch_size - 0.5);
          keypoints.emplace_back(x, y, static_cast<float>(config.window_sizes[w] / 6.0), 0.0f);
        }
      }
    }
    cv::Mat descriptors;
    sift->compute(grey, keypoints, descriptors);
    if (descriptors.rows != static_cast<int>(tokens * windows)) {
      throw std::runtime_error("dense-sift encoder: SIFT returned " + std::to_string(descriptors.rows) +
                               " descriptors for " + std::to_string(tokens * windows) + " patch windows");
    }
    toRootSift(descriptors);
    descriptors *= window_share;
    for (size_t w = 0; w < windows; ++w) {
      descriptors.rowRange(static_cast<int>(tokens * w), static_cast<int>(tokens * (w + 1)))
          .copyTo(token_rows.colRange(static_cast<int>(128 * w), static_cast<int>(128 * (w + 1))));
    }
  }
  Dust3rEncoding encoding;
  encoding.tokens = out.to(images.device());
  encoding.positions = patchPositions(batch, rows, cols, images.device());
  encoding.height = height;
  encoding.width = width;
  return encoding;
}

}  // namespace ffloc
