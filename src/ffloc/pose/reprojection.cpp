#include "ffloc/pose/reprojection.h"

#include <Eigen/Geometry>
#include <limits>

namespace ffloc {

double squaredReprojectionError(const Intrinsics& camera, const Pose& world_to_camera,
                                const Eigen::Vector2d& pixel, const Eigen::Vector3d& point) {
  const Eigen::Vector3d p = world_to_camera.R * point + world_to_camera.t;
  if (!(p.z() > 0)) return std::numeric_limits<double>::infinity();
  const double du = camera.fx * p.x() / p.z() + camera.cx - pixel.x();
  const double dv = camera.fy * p.y() / p.z() + camera.cy - pixel.y();
  return du * du + dv * dv;
}

Eigen::Matrix<double, 2, 6> projectionJacobian(const Intrinsics& camera, const Eigen::Vector3d& point_in_camera) {
  const Eigen::Vector3d& p = point_in_camera;
  const double inv_z = 1.0 / p.z();
  const double x = p.x() * inv_z, y = p.y() * inv_z;
  Eigen::Matrix<double, 2, 3> d_projection;
  d_projection << camera.fx * inv_z, 0, -camera.fx * x * inv_z,  //
      0, camera.fy * inv_z, -camera.fy * y * inv_z;
  Eigen::Matrix3d d_point_d_omega;
  d_point_d_omega << 0, p.z(), -p.y(), -p.z(), 0, p.x(), p.y(), -p.x(), 0;  // -[p]x
  Eigen::Matrix<double, 2, 6> J;
  J.leftCols<3>() = d_projection * d_point_d_omega;
  J.rightCols<3>() = d_projection;
  return J;
}

std::vector<int> findInliers(const std::vector<Eigen::Vector2d>& pixels,
                             const std::vector<Eigen::Vector3d>& points, const Intrinsics& camera,
                             const Pose& world_to_camera, double threshold_px) {
  const double threshold_squared = threshold_px * threshold_px;
  std::vector<int> inliers;
  for (size_t i = 0; i < pixels.size(); ++i)
    if (squaredReprojectionError(camera, world_to_camera, pixels[i], points[i]) < threshold_squared)
      inliers.push_back(static_cast<int>(i));
  return inliers;
}

Pose perturbedLeft(const Pose& world_to_camera, const Eigen::Matrix<double, 6, 1>& step) {
  const Eigen::Vector3d omega = step.head<3>();
  const double angle = omega.norm();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  if (angle > 0) rotation = Eigen::AngleAxisd(angle, omega / angle).toRotationMatrix();
  Pose updated;
  updated.R = rotation * world_to_camera.R;
  updated.t = rotation * world_to_camera.t + step.tail<3>();
  return updated;
}

}  // namespace ffloc
