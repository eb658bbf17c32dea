#include "ffloc/geometry/rays.h"

#include <cmath>
#include <limits>

namespace ffloc {

Ray pixelRay(const Intrinsics& camera, const Pose& camera_to_world, const Eigen::Vector2d& pixel) {
  const Eigen::Vector3d in_camera((pixel.x() - camera.cx) / camera.fx, (pixel.y() - camera.cy) / camera.fy, 1.0);
  return {camera_to_world.t, camera_to_world.R * in_camera};
}

std::vector<Ray> patchRays(const Intrinsics& camera, const Pose& camera_to_world, int patch_size) {
  const int rows = camera.height / patch_size;
  const int cols = camera.width / patch_size;
  std::vector<Ray> rays;
  rays.reserve(static_cast<size_t>(rows) * cols);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c)
      rays.push_back(pixelRay(camera, camera_to_world,
                              {(c + 0.5) * patch_size - 0.5, (r + 0.5) * patch_size - 0.5}));
  return rays;
}

std::vector<Eigen::Vector3d> patchCentrePoints(const cv::Mat1f& depth, const Intrinsics& camera,
                                               const Pose& camera_to_world, int patch_size) {
  const int rows = camera.height / patch_size;
  const int cols = camera.width / patch_size;
  std::vector<Eigen::Vector3d> points;
  points.reserve(static_cast<size_t>(rows) * cols);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const double u = (c + 0.5) * patch_size - 0.5, v = (r + 0.5) * patch_size - 0.5;
      const long x = std::lround(u), y = std::lround(v);
      const float d = x < depth.cols && y < depth.rows ? depth(static_cast<int>(y), static_cast<int>(x)) : 0.0f;
      points.push_back(d > 0 ? Eigen::Vector3d(camera_to_world * camera.backproject({u, v}, d))
                             : Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
    }
  }
  return points;
}

}  // namespace ffloc
