#pragma once

#include <Eigen/Core>
#include <vector>

#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"

namespace ffloc {

// Whether a pose's pairs fit the focal length they were given. A query with a wrong focal length
// still finds hundreds of inliers: the pose slides along the optical axis to make up for it and
// lands metres off. Fitting one focal scale beside the pose tells it apart where the scene's
// depth relief determines the focal length (on a far plane it does not: scale_sigma is then
// large).
struct FocalFit {
  bool valid = false;      // false with fewer than 5 pairs in front of the camera, or a singular fit
  double scale = 1;        // the focal length the pairs fit best, over the one given
  double log_scale_sigma = 0;  // predicted standard deviation of ln(scale), from the residuals
};

// Gauss-Newton (Levenberg-Marquardt) on the pose and ln(scale) over the pairs `indices` (the
// inliers), starting from `world_to_camera` and scale 1; fx and fy scale together, the principal
// point stays.
FocalFit fitFocalScale(const std::vector<Eigen::Vector2d>& pixels, const std::vector<Eigen::Vector3d>& points,
                       const std::vector<int>& indices, const Intrinsics& camera, const Pose& world_to_camera);

}  // namespace ffloc
