#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"
#include "ffloc/pose/pnp.h"

namespace ffloc {

// cv::solvePnPRansac in its USAC form (P3P minimal solver, MSAC scoring, inner + iterative
// local optimisation), then cv::solvePnPRefineLM on its inliers when options.refine. Returns the
// world-to-camera pose (X_cam = R * X_world + t), or nothing when OpenCV finds no model; OpenCV
// exceptions are caught and read as "no model".
std::optional<Pose> opencvUsacPnp(const std::vector<Eigen::Vector2d>& pixels,
                                  const std::vector<Eigen::Vector3d>& points,
                                  const Intrinsics& camera, const PnpOptions& options);

}  // namespace ffloc
