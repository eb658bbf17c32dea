#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"

namespace ffloc {

// One sighting of a 3D point: a pixel of an undistorted pinhole image with known K and
// camera-to-world pose.
struct Observation {
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  Pose camera_to_world;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();

  Observation() = default;
  Observation(const Intrinsics& camera, const Pose& pose, const Eigen::Vector2d& pixel_in)
      : K(camera.K()), camera_to_world(pose), pixel(pixel_in) {}
};

// Acceptance tests for a triangulated point. A point must be in front of every camera, reproject
// within max_reprojection_error_px in every view, and be seen under at least min_angle_deg by some
// pair of views (narrower rays give depth that the pixel noise does not determine).
struct TriangulationOptions {
  double max_reprojection_error_px = 4.0;
  double min_angle_deg = 1.5;
  // Gauss-Newton on the reprojection error after the algebraic (DLT) solution.
  bool refine = true;
  int max_refine_iterations = 10;
};

// Multi-view linear triangulation (homogeneous DLT in normalised image coordinates, world frame
// centred and scaled on the cameras for conditioning), optionally refined, then checked.
// nullopt with fewer than two observations, for degenerate geometry (parallel rays, a point at
// infinity) or when a check fails.
std::optional<Eigen::Vector3d> triangulate(const std::vector<Observation>& observations,
                                           const TriangulationOptions& options = {});

// triangulate() that also survives wrong observations (mismatched pixels). When the point from
// all views fails, every pair of views proposes a point (an exhaustive RANSAC: tracks are short),
// the proposal that most views agree with wins, and its agreeing views are triangulated again.
// `inliers` (when given) receives one flag per observation: the views the point was made from.
std::optional<Eigen::Vector3d> triangulateRobust(const std::vector<Observation>& observations,
                                                 const TriangulationOptions& options = {},
                                                 std::vector<bool>* inliers = nullptr);

// Pixel distance between the observation and the projection of `point`; +inf when the point is
// not in front of the camera.
double reprojectionError(const Observation& observation, const Eigen::Vector3d& point);

// The largest angle, in degrees, between the rays from two of the observing cameras to `point`.
double maxTriangulationAngleDeg(const std::vector<Observation>& observations, const Eigen::Vector3d& point);

}  // namespace ffloc
