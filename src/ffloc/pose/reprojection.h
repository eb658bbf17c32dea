#pragma once

#include <Eigen/Core>
#include <vector>

#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"

namespace ffloc {

// Squared pixel distance between `pixel` and the pinhole projection of the world `point`;
// +inf when the point is not in front of the camera, so no threshold accepts it.
double squaredReprojectionError(const Intrinsics& camera, const Pose& world_to_camera,
                                const Eigen::Vector2d& pixel, const Eigen::Vector3d& point);

// Jacobian of the pixel projection of `point_in_camera` (z > 0) with respect to a left
// perturbation of world_to_camera, X_cam -> exp([omega]x) X_cam + v, parameters (omega, v). The
// perturbation rotates about the camera centre, so omega leaves the centre where it is.
Eigen::Matrix<double, 2, 6> projectionJacobian(const Intrinsics& camera, const Eigen::Vector3d& point_in_camera);

// world_to_camera moved by that left perturbation: X_cam -> exp([omega]x) X_cam + v, step (omega, v).
Pose perturbedLeft(const Pose& world_to_camera, const Eigen::Matrix<double, 6, 1>& step);

// Indices of the pairs whose reprojection error is below `threshold_px` (positive depth only).
std::vector<int> findInliers(const std::vector<Eigen::Vector2d>& pixels,
                             const std::vector<Eigen::Vector3d>& points, const Intrinsics& camera,
                             const Pose& world_to_camera, double threshold_px);

}  // namespace ffloc
