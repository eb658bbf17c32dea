#pragma once

#include <Eigen/Core>
#include <vector>

#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"

namespace ffloc {

enum class RefineLoss {
  kSquared,  // plain least squares: for a set already cleaned of outliers
  kCauchy,   // rho(s) = c^2 log(1 + s / c^2): residuals well above c lose their pull
};

struct RefinePoseOptions {
  int max_iterations = 25;
  RefineLoss loss = RefineLoss::kCauchy;
  double loss_scale_px = 1.0;  // c of the Cauchy loss, in pixels
  // Stops once an accepted step moves the pose by less than step_tolerance (radians + scene
  // units) or lowers the cost by less than relative_decrease_tolerance of it. IRLS on a robust
  // loss converges only linearly; past these the pose no longer moves in any digit that matters
  // against pixel noise.
  double step_tolerance = 1e-8;
  double relative_decrease_tolerance = 1e-6;
};

struct RefinePoseSummary {
  int iterations = 0;
  double initial_cost = 0;  // sum of rho(squared pixel error) over the points in front
  double final_cost = 0;
};

// Levenberg-Marquardt on SE(3) minimising the robustified pixel reprojection error of the pairs
// `indices` under `world_to_camera` (X_cam = R * X_world + t), which it updates in place.
// Points behind the camera are left out, and no step may push a point behind it.
RefinePoseSummary refinePose(const std::vector<Eigen::Vector2d>& pixels,
                             const std::vector<Eigen::Vector3d>& points,
                             const std::vector<int>& indices, const Intrinsics& camera,
                             const RefinePoseOptions& options, Pose* world_to_camera);

}  // namespace ffloc
