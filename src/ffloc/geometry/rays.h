#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"

namespace ffloc {

// A camera ray: origin at the camera centre, direction (K R^T)^-1 [u, v, 1]^T expressed in the
// frame of `camera_to_world` (i.e. R K^-1 [u, v, 1]^T), not normalised to unit length so that it
// matches the paper's definition exactly.
struct Ray {
  Eigen::Vector3d origin;
  Eigen::Vector3d direction;
};

Ray pixelRay(const Intrinsics& camera, const Pose& camera_to_world, const Eigen::Vector2d& pixel);

// Rays through the centres of the patch_size x patch_size patches of an image of
// camera.width x camera.height, row-major (token n = row n / cols, col n % cols). The centre of
// patch (r, c) is pixel ((c + 0.5) * patch - 0.5, (r + 0.5) * patch - 0.5).
std::vector<Ray> patchRays(const Intrinsics& camera, const Pose& camera_to_world, int patch_size = 16);

// The world point seen at each patch centre (as patchRays), from the image's z-depth map in
// the same pixel grid, read at the nearest pixel; NaN where the depth there is 0 (missing).
std::vector<Eigen::Vector3d> patchCentrePoints(const cv::Mat1f& depth, const Intrinsics& camera,
                                               const Pose& camera_to_world, int patch_size = 16);

}  // namespace ffloc
