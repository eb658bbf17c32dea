#include "ffloc/pose/focal_scan.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

namespace ffloc {
namespace {

Intrinsics trueCamera() { return {500, 500, 320, 240, 640, 480, {}}; }

// 300 pairs of a camera with trueCamera()'s intrinsics, points 1-4 m deep, 1 px of noise, and
// 300 wrong pairs: the right focal length explains half of them.
Correspondences observed(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 640), v(0, 480), depth(1, 4);
  std::normal_distribution<double> noise(0, 1);
  Pose camera_to_world;
  camera_to_world.R = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, -1).normalized()).toRotationMatrix();
  camera_to_world.t = Eigen::Vector3d(0.5, -0.2, 1.0);
  Correspondences pairs;
  for (int i = 0; i < 600; ++i) {
    const Eigen::Vector2d pixel(u(rng), v(rng));
    const Eigen::Vector2d seen = i < 300 ? Eigen::Vector2d(pixel + Eigen::Vector2d(noise(rng), noise(rng)))
                                         : Eigen::Vector2d(u(rng), v(rng));
    pairs.add(seen, camera_to_world * trueCamera().backproject(pixel, depth(rng)), 3.0f);
  }
  return pairs;
}

TEST(FocalScan, AWrongFocalLengthGivenFindsTheRightOneWithMoreInliers) {
  const Correspondences pairs = observed(3);
  Intrinsics given = trueCamera();
  given.fx *= 0.8;
  given.fy *= 0.8;
  const PnpResult pose = estimatePose(pairs, given);
  ASSERT_TRUE(pose.ok());
  const FocalScan scan = scanFocalLengths(pairs, given, PnpOptions{}, pose.inliers);
  ASSERT_TRUE(scan.valid);
  EXPECT_TRUE(scan.factor == 1.2 || scan.factor == 1.3) << scan.factor;
  EXPECT_GE(scan.inlier_gain, 1.25) << pose.inliers << " inliers at the focal length given";
}

TEST(FocalScan, TheRightFocalLengthIsNotBeaten) {
  const Correspondences pairs = observed(4);
  const PnpResult pose = estimatePose(pairs, trueCamera());
  ASSERT_TRUE(pose.ok());
  const FocalScan scan = scanFocalLengths(pairs, trueCamera(), PnpOptions{}, pose.inliers);
  ASSERT_TRUE(scan.valid);
  EXPECT_LT(scan.inlier_gain, 1.0);
}

TEST(FocalScan, NoPoseAtAnyFocalLengthIsNoScan) {
  Correspondences three;
  for (int i = 0; i < 3; ++i) three.add({100.0 * i, 50}, {1.0 * i, 0, 3}, 3.0f);
  EXPECT_FALSE(scanFocalLengths(three, trueCamera(), PnpOptions{}, 3).valid);
}

}  // namespace
}  // namespace ffloc
