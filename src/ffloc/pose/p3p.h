#pragma once

#include <Eigen/Core>
#include <array>
#include <vector>

#include "ffloc/geometry/pose.h"

namespace ffloc {

// Minimal absolute pose from three 2D-3D pairs, after Persson & Nordberg, "Lambda Twist: An
// Accurate Fast Robust Perspective Three Point (P3P) Solver" (ECCV 2018): the three distance
// constraints on the depths are reduced to a degenerate conic pencil, which splits into two
// planes, each cut with one remaining conic.
//
// `bearings` are unit rays in the camera frame, `points` the matching world points. Appends each
// real solution with positive depths to `world_to_camera` (X_cam = R * X_world + t) and returns
// how many it appended (at most 4). Returns 0 for (nearly) collinear world points, and appends
// nothing that is not a rotation to kRigidRotationTolerance (rays that nearly coincide).
int solveP3P(const std::array<Eigen::Vector3d, 3>& bearings,
             const std::array<Eigen::Vector3d, 3>& points, std::vector<Pose>* world_to_camera);

}  // namespace ffloc
