#include "ffloc/pose/reprojection.h"

#include <gtest/gtest.h>

#include <cmath>

namespace ffloc {
namespace {

Intrinsics testCamera() { return {500, 400, 320, 240, 640, 480, {}}; }

TEST(Reprojection, MeasuresPixelDistanceOfTheProjection) {
  Pose world_to_camera;
  world_to_camera.t = Eigen::Vector3d(0, 0, 1);
  // (0.2, -0.1, 1) in the world is (0.2, -0.1, 2) in the camera: pixel (370, 220).
  const Eigen::Vector3d point(0.2, -0.1, 1.0);
  EXPECT_NEAR(squaredReprojectionError(testCamera(), world_to_camera, {370, 220}, point), 0.0, 1e-18);
  EXPECT_NEAR(squaredReprojectionError(testCamera(), world_to_camera, {373, 224}, point), 25.0, 1e-9);
}

TEST(Reprojection, PointsBehindTheCameraAreNeverInliers) {
  const Pose identity;
  // (-0.2, 0.1, -2) projects to the same pixel as (0.2, -0.1, 2), but lies behind the camera.
  const std::vector<Eigen::Vector3d> points = {{0.2, -0.1, 2.0}, {-0.2, 0.1, -2.0}, {0.2, -0.1, 0.0}};
  const std::vector<Eigen::Vector2d> pixels = {{370, 220}, {370, 220}, {370, 220}};
  EXPECT_TRUE(std::isinf(squaredReprojectionError(testCamera(), identity, pixels[1], points[1])));
  EXPECT_EQ(findInliers(pixels, points, testCamera(), identity, 8.0), (std::vector<int>{0}));
}

TEST(Reprojection, InlierThresholdIsInPixels) {
  const Pose identity;
  const std::vector<Eigen::Vector3d> points(3, Eigen::Vector3d(0, 0, 1));
  const std::vector<Eigen::Vector2d> pixels = {{320, 240}, {327.9, 240}, {320, 248.1}};
  EXPECT_EQ(findInliers(pixels, points, testCamera(), identity, 8.0), (std::vector<int>{0, 1}));
}

}  // namespace
}  // namespace ffloc
