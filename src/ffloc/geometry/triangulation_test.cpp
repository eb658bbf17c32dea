#include "ffloc/geometry/triangulation.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

namespace ffloc {
namespace {

Intrinsics testCamera() { return {800, 780, 319.5, 241.0, 640, 480, {}}; }

// A camera at `centre` looking at `target` (OpenCV axes, world up is -y).
Pose lookAt(const Eigen::Vector3d& centre, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - centre).normalized();
  Eigen::Vector3d x = Eigen::Vector3d(0, -1, 0).cross(z);
  if (x.norm() < 1e-6) x = Eigen::Vector3d(1, 0, 0).cross(z);
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Pose pose;
  pose.R.col(0) = x;
  pose.R.col(1) = y;
  pose.R.col(2) = z;
  pose.t = centre;
  return pose;
}

Observation observe(const Intrinsics& camera, const Pose& pose, const Eigen::Vector3d& point) {
  const Eigen::Vector3d p = pose.R.transpose() * (point - pose.t);
  return Observation(camera, pose, camera.project(p));
}

TEST(Triangulation, RecoversExactPointFromManyViews) {
  const Intrinsics camera = testCamera();
  // Far from the origin on purpose: the conditioning must cope with large world coordinates.
  const Eigen::Vector3d offset(1200.0, -350.0, 80.0);
  const Eigen::Vector3d point = offset + Eigen::Vector3d(0.3, -0.2, 5.0);
  std::vector<Observation> observations;
  for (int k = 0; k < 5; ++k) {
    const Eigen::Vector3d centre = offset + Eigen::Vector3d(-1.0 + 0.5 * k, 0.1 * k, 0.2 * (k % 2));
    observations.push_back(observe(camera, lookAt(centre, point + Eigen::Vector3d(0.1 * k, 0, 0)), point));
  }
  for (bool refine : {false, true}) {
    TriangulationOptions options;
    options.refine = refine;
    const std::optional<Eigen::Vector3d> estimate = triangulate(observations, options);
    ASSERT_TRUE(estimate.has_value()) << "refine=" << refine;
    EXPECT_LT((*estimate - point).norm(), 1e-9) << "refine=" << refine;
  }
}

TEST(Triangulation, RecoversExactPointFromTwoViewsWithDifferentCameras) {
  Intrinsics other = testCamera();
  other.fx = 2759.48;
  other.fy = 2764.16;
  other.cx = 1520.69;
  other.cy = 1006.81;
  const Eigen::Vector3d point(-2.0, 1.0, 12.0);
  const std::vector<Observation> observations = {
      observe(testCamera(), lookAt({0, 0, 0}, point), point),
      observe(other, lookAt({1.5, 0.2, 0.5}, point + Eigen::Vector3d(0.5, 0.5, 0)), point)};
  const std::optional<Eigen::Vector3d> estimate = triangulate(observations);
  ASSERT_TRUE(estimate.has_value());
  EXPECT_LT((*estimate - point).norm(), 1e-9);
  for (const Observation& o : observations) EXPECT_LT(reprojectionError(o, *estimate), 1e-6);
}

TEST(Triangulation, RejectsParallelRays) {
  const Intrinsics camera = testCamera();
  Pose a, b;
  b.t = Eigen::Vector3d(1, 0, 0);
  // The same pixel in two translated cameras with the same orientation: parallel rays, a point at
  // infinity.
  const std::vector<Observation> observations = {Observation(camera, a, {100, 200}), Observation(camera, b, {100, 200})};
  EXPECT_FALSE(triangulate(observations).has_value());
  TriangulationOptions no_angle_check;
  no_angle_check.min_angle_deg = 0;
  EXPECT_FALSE(triangulate(observations, no_angle_check).has_value());
  EXPECT_FALSE(triangulateRobust(observations).has_value());
}

TEST(Triangulation, RejectsCamerasAtOneCentre) {
  const Intrinsics camera = testCamera();
  const Eigen::Vector3d point(0.5, 0.2, 4.0);
  const std::vector<Observation> observations = {observe(camera, lookAt({0, 0, 0}, point), point),
                                                 observe(camera, lookAt({0, 0, 0}, {1, 0, 4}), point),
                                                 observe(camera, lookAt({0, 0, 0}, {0, 1, 4}), point)};
  EXPECT_FALSE(triangulate(observations).has_value());
  EXPECT_FALSE(triangulateRobust(observations).has_value());
}

TEST(Triangulation, RejectsNarrowTriangulationAngle) {
  const Intrinsics camera = testCamera();
  const Eigen::Vector3d point(0, 0, 10.0);
  // A 0.1 m baseline at 10 m distance: about 0.57 degrees.
  const std::vector<Observation> observations = {observe(camera, lookAt({0, 0, 0}, point), point),
                                                 observe(camera, lookAt({0.1, 0, 0}, point), point)};
  EXPECT_NEAR(maxTriangulationAngleDeg(observations, point), std::atan(0.01) * 180 / M_PI, 1e-9);
  EXPECT_FALSE(triangulate(observations).has_value());
  TriangulationOptions permissive;
  permissive.min_angle_deg = 0.5;
  const std::optional<Eigen::Vector3d> estimate = triangulate(observations, permissive);
  ASSERT_TRUE(estimate.has_value());
  EXPECT_LT((*estimate - point).norm(), 1e-8);
}

TEST(Triangulation, RejectsPointBehindCameras) {
  const Intrinsics camera = testCamera();
  const Eigen::Vector3d point(0, 0, -5.0);
  // Cameras looking along +z see the point's mirror image; the exact rays meet behind them.
  Pose a, b;
  b.t = Eigen::Vector3d(1, 0, 0);
  const auto mirrored = [&](const Pose& pose) {
    const Eigen::Vector3d p = pose.R.transpose() * (point - pose.t);
    return Observation(camera, pose, camera.project(p));
  };
  const std::vector<Observation> observations = {mirrored(a), mirrored(b)};
  EXPECT_FALSE(triangulate(observations).has_value());
  EXPECT_TRUE(std::isinf(reprojectionError(observations[0], point)));
}

TEST(Triangulation, RejectsTooFewObservationsAndLargeReprojectionError) {
  const Intrinsics camera = testCamera();
  const Eigen::Vector3d point(0.2, 0.1, 6.0);
  std::vector<Observation> observations = {observe(camera, lookAt({0, 0, 0}, point), point)};
  EXPECT_FALSE(triangulate({}).has_value());
  EXPECT_FALSE(triangulate(observations).has_value());
  observations.push_back(observe(camera, lookAt({1, 0, 0}, point), point));
  observations.push_back(observe(camera, lookAt({0, 1, 0}, point), point));
  ASSERT_TRUE(triangulate(observations).has_value());
  // 30 px off in one view cannot be absorbed by the other two views within 4 px.
  observations[2].pixel.x() += 30;
  EXPECT_FALSE(triangulate(observations).has_value());
}

TEST(Triangulation, RobustVariantDropsMismatchedViews) {
  const Intrinsics camera = testCamera();
  const Eigen::Vector3d point(0.4, -0.3, 8.0);
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.5);
  std::vector<Observation> observations;
  for (int k = 0; k < 6; ++k) {
    const Eigen::Vector3d centre(std::cos(k) * 1.5, 0.3 * std::sin(2.0 * k), 0.2 * k);
    Observation o = observe(camera, lookAt(centre, point), point);
    o.pixel += Eigen::Vector2d(noise(rng), noise(rng));
    observations.push_back(o);
  }
  // Two wrong matches, far from where the point projects.
  observations[1].pixel += Eigen::Vector2d(60, -25);
  observations[4].pixel += Eigen::Vector2d(-40, 90);
  EXPECT_FALSE(triangulate(observations).has_value());

  std::vector<bool> inliers;
  const std::optional<Eigen::Vector3d> estimate = triangulateRobust(observations, {}, &inliers);
  ASSERT_TRUE(estimate.has_value());
  EXPECT_LT((*estimate - point).norm(), 0.05);
  EXPECT_EQ(inliers, (std::vector<bool>{true, false, true, true, false, true}));
}

TEST(Triangulation, RobustVariantFailsWhenNoTwoViewsAgree) {
  const Intrinsics camera = testCamera();
  const Eigen::Vector3d point(0, 0, 8.0);
  std::vector<Observation> observations;
  for (int k = 0; k < 3; ++k) observations.push_back(observe(camera, lookAt({k - 1.0, 0, 0}, point), point));
  // Vertical offsets cannot be explained by a horizontal baseline.
  observations[0].pixel.y() += 50;
  observations[2].pixel.y() -= 50;
  std::vector<bool> inliers;
  EXPECT_FALSE(triangulateRobust(observations, {}, &inliers).has_value());
  EXPECT_EQ(inliers, (std::vector<bool>{false, false, false}));
}

}  // namespace
}  // namespace ffloc
