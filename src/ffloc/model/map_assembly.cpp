#include "ffloc/model/map_assembly.h"

#include <cmath>

#include "ffloc/core/error.h"
#include "ffloc/geometry/rays.h"
#include "ffloc/model/ray_encoding.h"

namespace ffloc {

MapLayout planMap(const std::vector<MapCamera>& cameras, int patch_size, int64_t token_count, uint64_t seed) {
  if (cameras.empty()) throwInputError("map", 0, "no mapping image to build the map from");
  std::vector<Pose> poses;
  std::vector<std::string> names;
  for (const MapCamera& camera : cameras) {
    poses.push_back(camera.camera_to_world);
    names.push_back(camera.name);
  }
  MapLayout layout;
  layout.normalization = SceneNormalization::fromMappingPoses(poses, 0, names);
  for (const MapCamera& camera : cameras) {
    const int rows = camera.intrinsics.height / patch_size, cols = camera.intrinsics.width / patch_size;
    if (rows < 1 || cols < 1) {
      throwInputError(camera.name, 0, "image of " + std::to_string(camera.intrinsics.width) + "x" +
                                          std::to_string(camera.intrinsics.height) + " px holds no " +
                                          std::to_string(patch_size) + " px patch");
    }
    layout.rays.push_back(
        rayTensor(patchRays(camera.intrinsics, layout.normalization.normalize(camera.camera_to_world), patch_size)));
    layout.tokens_per_image.push_back(static_cast<int64_t>(rows) * cols);
  }
  layout.indices = sampleMapTokenIndices(layout.tokens_per_image, token_count, seed);
  return layout;
}

MapTokens assembleMapTokens(const MapLayout& layout, const std::vector<Dust3rEncoding>& encodings,
                            const std::vector<at::Tensor>& points) {
  return gatherMapTokens(encodings, layout.rays, layout.indices, points);
}

Correspondences queryCorrespondences(const Dust3rPointMap& query, int64_t batch_index,
                                     const SceneNormalization& normalization, int64_t grid_stride,
                                     const PreprocessGeometry* to_original) {
  if (grid_stride < 1) throw std::invalid_argument("queryCorrespondences: grid_stride must be at least 1");
  const double stride = static_cast<double>(grid_stride);
  const at::Tensor points = query.pts3d[batch_index].to(at::kDouble).contiguous();  // (H, W, 3)
  const at::Tensor confidence = query.conf[batch_index].to(at::kFloat).contiguous();
  const int64_t height = points.size(0), width = points.size(1);
  const double* xyz = points.data_ptr<double>();
  const float* conf = confidence.data_ptr<float>();
  Correspondences out;
  out.reserve(static_cast<size_t>(height * width));
  for (int64_t y = 0; y < height; ++y) {
    for (int64_t x = 0; x < width; ++x) {
      const int64_t i = y * width + x;
      const Eigen::Vector3d point(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
      if (!point.allFinite() || !std::isfinite(conf[i])) continue;
      const Eigen::Vector2d pixel((x + 0.5) * stride - 0.5, (y + 0.5) * stride - 0.5);
      out.add(to_original ? to_original->toOriginal(pixel) : pixel, normalization.toWorld(point), conf[i]);
    }
  }
  return out;
}

}  // namespace ffloc
