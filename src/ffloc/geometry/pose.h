#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>

namespace ffloc {

// A rigid transform. The project convention: a frame's pose is camera-to-world
// (X_world = R * X_cam + t), OpenCV camera axes (x right, y down, z forward), metres or the
// dataset's units. Readers convert to this; nothing deeper does.
struct Pose {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();

  static Pose identity() { return {}; }
  static Pose fromMatrix(const Eigen::Matrix4d& T);
  // Hamilton quaternion, scalar first, as COLMAP and hloc write it.
  static Pose fromQuaternion(double qw, double qx, double qy, double qz, const Eigen::Vector3d& t);

  Eigen::Matrix4d matrix() const;
  Eigen::Quaterniond quaternion() const { return Eigen::Quaterniond(R).normalized(); }
  Pose inverse() const;
  Pose operator*(const Pose& other) const;
  Eigen::Vector3d operator*(const Eigen::Vector3d& point) const { return R * point + t; }

  // For a camera-to-world pose, the camera centre in the world.
  const Eigen::Vector3d& centre() const { return t; }
  bool isFinite() const;
};

// max |R^T R - I|: how far a matrix is from orthonormal.
double orthogonalityError(const Eigen::Matrix3d& R);

// A matrix this close to orthonormal is a rotation as written: readers keep it (so files round-trip
// exactly) and map files accept it. Readers project anything further off, up to the 1e-2 that text
// with lost digits reaches, so no rotation beyond this reaches a map (a manifest pose 1e-3 off was
// mapped as written and the map file then refused to load).
inline constexpr double kRigidRotationTolerance = 1e-6;

// Re-orthonormalises a nearly-orthonormal matrix (parsed text loses digits) with an SVD.
// Returns false when the input is far from a rotation (|det - 1| or orthogonality > tolerance).
bool projectToRotation(Eigen::Matrix3d& R, double tolerance = 1e-2);

// Angle of R_a^T R_b, in degrees, robust near 0 and 180.
double rotationErrorDeg(const Pose& estimate, const Pose& truth);
// Distance between the camera centres of two camera-to-world poses, in the poses' units.
double translationError(const Pose& estimate, const Pose& truth);

std::string toString(const Pose& pose);

}  // namespace ffloc
