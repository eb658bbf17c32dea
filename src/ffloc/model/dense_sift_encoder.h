#pragma once

#include <ATen/core/Tensor.h>

#include <string>
#include <vector>

#include "ffloc/model/dust3r_model.h"

namespace ffloc {

// A frozen encoder that needs no training (issue: a learned model at our compute): one token per
// patch of the DUSt3R grid, the RootSIFT descriptors of the patch centre at several window sizes,
// upright, concatenated and scaled to unit L2 norm. Dot products of two tokens are then the
// descriptors' Hellinger similarity in [0, 1], which the matching head starts from.
struct DenseSiftConfig {
  // Side of the square each descriptor covers, in pixels of the preprocessed image (SIFT's 4 x 4
  // cells of 3 sigma, so OpenCV's keypoint size is a sixth of it). A patch is 16 px; wider
  // windows add the context that tells repeated texture apart.
  std::vector<double> window_sizes = {24.0, 48.0};

  int64_t tokenDim() const { return 128 * static_cast<int64_t>(window_sizes.size()); }
  // InputError naming the field.
  void validate(const std::string& origin = "dense-sift encoder") const;
};

// images: (B, 3, H, W) float in [-1, 1] (normalizedImageTensor), H and W multiples of
// `patch_size`. Tokens (B, rows * cols, tokenDim()) float32 in row-major patch order, positions
// as patchPositions(). The keypoint of patch (r, c) is its centre ((c + 0.5) p - 0.5,
// (r + 0.5) p - 0.5), where the token's ray also passes (rays.h).
Dust3rEncoding denseSiftEncode(const at::Tensor& images, int64_t patch_size, const DenseSiftConfig& config);

}  // namespace ffloc
