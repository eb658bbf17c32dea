#include "ffloc/pose/pose_covariance.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <string>

#include "ffloc/core/error.h"
#include "ffloc/pose/reprojection.h"

namespace ffloc {

void PoseCovarianceOptions::check() const {
  if (!(pixel_sigma >= 0 && std::isfinite(pixel_sigma)))
    throw InputError("pixel_sigma: must be finite and at least 0, got " + std::to_string(pixel_sigma));
}

PoseCovariance estimatePoseCovariance(const std::vector<Eigen::Vector2d>& pixels,
                                      const std::vector<Eigen::Vector3d>& points, const std::vector<int>& indices,
                                      const Intrinsics& camera, const Pose& world_to_camera,
                                      const PoseCovarianceOptions& options) {
  options.check();
  PoseCovariance result;
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
  double squared_residuals = 0;
  for (int i : indices) {
    const Eigen::Vector3d p = world_to_camera * points[i];
    if (!(p.z() > 0)) continue;
    const Eigen::Matrix<double, 2, 6> J = projectionJacobian(camera, p);
    information.noalias() += J.transpose() * J;
    squared_residuals += (camera.project(p) - pixels[i]).squaredNorm();
    ++result.pairs;
  }
  // Four pairs leave two degrees of freedom for the noise estimate; fewer leave none.
  if (result.pairs < 4) return result;
  result.residual_sigma_px = std::sqrt(squared_residuals / (2 * result.pairs - 6));
  result.pixel_sigma_px = options.pixel_sigma > 0 ? options.pixel_sigma : result.residual_sigma_px;

  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> factor(information);
  if (factor.info() != Eigen::Success || !factor.isPositive() ||
      factor.vectorD().minCoeff() <= 1e-12 * factor.vectorD().maxCoeff())
    return result;
  result.covariance = result.pixel_sigma_px * result.pixel_sigma_px *
                      factor.solve(Eigen::Matrix<double, 6, 6>::Identity());
  if (!result.covariance.allFinite()) return result;
  // The camera centre is C = -R^T t; under the perturbation it moves by -R^T v (omega turns the
  // camera about C).
  result.centre_covariance = world_to_camera.R.transpose() * result.covariance.bottomRightCorner<3, 3>() *
                             world_to_camera.R;
  result.centre_sigma = std::sqrt(result.centre_covariance.trace());
  result.rotation_sigma_deg = std::sqrt(result.covariance.topLeftCorner<3, 3>().trace()) * 180.0 / M_PI;
  result.valid = true;
  return result;
}

}  // namespace ffloc
