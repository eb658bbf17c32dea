#pragma once

#include <Eigen/Core>
#include <vector>

#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"

namespace ffloc {

struct PoseCovarianceOptions {
  // The standard deviation of the pixel noise, per axis. 0: estimated from the residuals of the
  // pairs given, sqrt(sum |r|^2 / (2n - 6)).
  double pixel_sigma = 0;

  // InputError naming the field for a value out of range or NaN.
  void check() const;
};

// The first-order (Gauss-Newton) uncertainty of a pose fitted to pixel observations: the
// covariance sigma^2 (J^T J)^-1 of the reprojection residuals' least-squares fit, linearised at
// the pose given. It assumes independent pixel noise and exact 3D points, so it bounds what
// the pairs can say, not a bias they share.
struct PoseCovariance {
  bool valid = false;  // false with fewer than 4 pairs in front of the camera or J^T J singular
  int pairs = 0;       // in front of the camera, the ones that count
  double residual_sigma_px = 0;  // estimated from the residuals, whatever pixel_sigma says
  double pixel_sigma_px = 0;     // the sigma the covariance is scaled by
  // Of the left perturbation of world_to_camera, X_cam -> exp([omega]x) X_cam + v, in the order
  // (omega, v): radians and scene units.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  // Of the camera centre in the world (scene units squared).
  Eigen::Matrix3d centre_covariance = Eigen::Matrix3d::Zero();
  // Root-mean-square error predicted for the camera centre (scene units) and the rotation angle
  // (degrees): the square roots of the covariances' traces.
  double centre_sigma = 0;
  double rotation_sigma_deg = 0;
};

// The uncertainty of `world_to_camera` given the pairs `indices` (typically the inliers of a
// refined pose). Throws InputError for invalid options.
PoseCovariance estimatePoseCovariance(const std::vector<Eigen::Vector2d>& pixels,
                                      const std::vector<Eigen::Vector3d>& points, const std::vector<int>& indices,
                                      const Intrinsics& camera, const Pose& world_to_camera,
                                      const PoseCovarianceOptions& options = {});

}  // namespace ffloc
