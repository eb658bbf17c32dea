#include "ffloc/geometry/pose.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <sstream>

namespace ffloc {

Pose Pose::fromMatrix(const Eigen::Matrix4d& T) {
  Pose p;
  p.R = T.topLeftCorner<3, 3>();
  p.t = T.topRightCorner<3, 1>();
  return p;
}

Pose Pose::fromQuaternion(double qw, double qx, double qy, double qz, const Eigen::Vector3d& t) {
  Pose p;
  p.R = Eigen::Quaterniond(qw, qx, qy, qz).normalized().toRotationMatrix();
  p.t = t;
  return p;
}

Eigen::Matrix4d Pose::matrix() const {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = R;
  T.topRightCorner<3, 1>() = t;
  return T;
}

Pose Pose::inverse() const {
  Pose p;
  p.R = R.transpose();
  p.t = -(p.R * t);
  return p;
}

Pose Pose::operator*(const Pose& other) const {
  Pose p;
  p.R = R * other.R;
  p.t = R * other.t + t;
  return p;
}

bool Pose::isFinite() const { return R.allFinite() && t.allFinite(); }

double orthogonalityError(const Eigen::Matrix3d& R) {
  return (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
}

bool projectToRotation(Eigen::Matrix3d& R, double tolerance) {
  if (!R.allFinite()) return false;
  const double orthogonality = orthogonalityError(R);
  if (orthogonality > tolerance || std::abs(R.determinant() - 1.0) > tolerance) return false;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  R = svd.matrixU() * svd.matrixV().transpose();
  return true;
}

double rotationErrorDeg(const Pose& estimate, const Pose& truth) {
  const Eigen::Matrix3d delta = estimate.R.transpose() * truth.R;
  // atan2 of (|sin|, cos) stays accurate where acos of the trace loses digits near 0.
  const Eigen::Vector3d axis(delta(2, 1) - delta(1, 2), delta(0, 2) - delta(2, 0), delta(1, 0) - delta(0, 1));
  const double sin_term = 0.5 * axis.norm();
  const double cos_term = 0.5 * (delta.trace() - 1.0);
  return std::atan2(sin_term, cos_term) * 180.0 / M_PI;
}

double translationError(const Pose& estimate, const Pose& truth) {
  return (estimate.centre() - truth.centre()).norm();
}

std::string toString(const Pose& pose) {
  std::ostringstream out;
  out.precision(9);
  out << pose.matrix();
  return out.str();
}

}  // namespace ffloc
