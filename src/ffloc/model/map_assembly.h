#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <string>
#include <vector>

#include "ffloc/geometry/map_camera.h"
#include "ffloc/geometry/normalization.h"
#include "ffloc/geometry/pose.h"
#include "ffloc/geometry/preprocess.h"
#include "ffloc/model/dust3r_model.h"
#include "ffloc/model/fastforward_model.h"
#include "ffloc/pose/correspondences.h"

namespace ffloc {

// The map's side of FastForward (paper, section 3.1), written once for localisation, training and
// the benchmark, since what the network learns only transfers when all three build the map alike.

// Everything about a map that precedes the encoder, from its cameras (the intrinsics of the
// preprocessed images whose tokens are used; their width and height give the token grid): the normalised frame with the first camera as
// P_0, each image's patch rays in that frame, and the sampled (image, token) pairs.
struct MapLayout {
  SceneNormalization normalization;
  std::vector<at::Tensor> rays;  // per image (1, T_k, 6) float32
  at::Tensor indices;            // (N, 2) int64 (image, token)
  std::vector<int64_t> tokens_per_image;
};

// InputError naming the image when a camera's size does not hold a whole token grid.
MapLayout planMap(const std::vector<MapCamera>& cameras, int patch_size, int64_t token_count, uint64_t seed);

// The layout's tokens gathered from the images' encodings (one per camera, batch 1), with their
// points when `points` holds one (1, T_k, 3) tensor per camera (normalised frame; NaN: none).
MapTokens assembleMapTokens(const MapLayout& layout, const std::vector<Dust3rEncoding>& encodings,
                            const std::vector<at::Tensor>& points = {});

// Every cell of sample `batch_index` of a query prediction with its point back in the world frame
// (non-finite predictions skipped). Cell (x, y) is the preprocessed image's pixel
// ((x + 0.5) s - 0.5, (y + 0.5) s - 0.5) for the model's grid stride s
// (FastForwardConfig::queryGridStride: 1 for a per-pixel head), which then goes back to the
// original image through `to_original` when given.
Correspondences queryCorrespondences(const Dust3rPointMap& query, int64_t batch_index,
                                     const SceneNormalization& normalization, int64_t grid_stride,
                                     const PreprocessGeometry* to_original = nullptr);

}  // namespace ffloc
