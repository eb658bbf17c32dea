#include "ffloc/pose/refine_pose.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <numeric>
#include <random>

namespace ffloc {
namespace {

Intrinsics testCamera() { return {500, 520, 320, 240, 640, 480, {}}; }

struct Observations {
  Pose world_to_camera;
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
};

Observations makeObservations(int count, double noise_px, std::mt19937_64& rng) {
  const Intrinsics camera = testCamera();
  Observations o;
  o.world_to_camera.R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  o.world_to_camera.t = Eigen::Vector3d(0.3, -0.2, 1.5);
  const Pose camera_to_world = o.world_to_camera.inverse();
  std::uniform_real_distribution<double> u(0, camera.width - 1), v(0, camera.height - 1), depth(1, 6);
  std::normal_distribution<double> noise(0, noise_px);
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector2d pixel(u(rng), v(rng));
    o.points.push_back(camera_to_world * camera.backproject(pixel, depth(rng)));
    o.pixels.push_back(pixel + Eigen::Vector2d(noise(rng), noise(rng)));
  }
  return o;
}

Pose perturbed(const Pose& pose) {
  Pose p;
  p.R = Eigen::AngleAxisd(0.05, Eigen::Vector3d(-1, 0.5, 2).normalized()).toRotationMatrix() * pose.R;
  p.t = pose.t + Eigen::Vector3d(0.1, -0.05, 0.08);
  return p;
}

std::vector<int> allIndices(size_t n) {
  std::vector<int> indices(n);
  std::iota(indices.begin(), indices.end(), 0);
  return indices;
}

TEST(RefinePose, ConvergesToTheExactPoseOnNoiseFreeData) {
  std::mt19937_64 rng(7);
  const Observations o = makeObservations(200, 0.0, rng);
  for (RefineLoss loss : {RefineLoss::kSquared, RefineLoss::kCauchy}) {
    Pose pose = perturbed(o.world_to_camera);
    RefinePoseOptions options;
    options.loss = loss;
    const RefinePoseSummary summary = refinePose(o.pixels, o.points, allIndices(o.pixels.size()), testCamera(), options, &pose);
    EXPECT_LT(summary.final_cost, 1e-12);
    EXPECT_LT(summary.final_cost, summary.initial_cost);
    EXPECT_LT((pose.R - o.world_to_camera.R).norm(), 1e-9);
    EXPECT_LT((pose.t - o.world_to_camera.t).norm(), 1e-9);
  }
}

TEST(RefinePose, CauchyLossResistsOutliersThatPullLeastSquaresOff) {
  std::mt19937_64 rng(8);
  Observations o = makeObservations(400, 0.5, rng);
  // A fifth of the pixels moved 40 px the same way: a strong, biased outlier set.
  for (size_t i = 0; i < o.pixels.size(); i += 5) o.pixels[i] += Eigen::Vector2d(40, 25);
  const std::vector<int> indices = allIndices(o.pixels.size());

  RefinePoseOptions robust;
  robust.loss = RefineLoss::kCauchy;
  robust.loss_scale_px = 1.0;
  Pose robust_pose = perturbed(o.world_to_camera);
  refinePose(o.pixels, o.points, indices, testCamera(), robust, &robust_pose);

  RefinePoseOptions squared = robust;
  squared.loss = RefineLoss::kSquared;
  Pose squared_pose = perturbed(o.world_to_camera);
  refinePose(o.pixels, o.points, indices, testCamera(), squared, &squared_pose);

  const double robust_error = (robust_pose.inverse().t - o.world_to_camera.inverse().t).norm();
  const double squared_error = (squared_pose.inverse().t - o.world_to_camera.inverse().t).norm();
  EXPECT_LT(robust_error, 5e-3);
  EXPECT_GT(squared_error, 5.0 * robust_error);
}

TEST(RefinePose, OnlyTheGivenIndicesCount) {
  std::mt19937_64 rng(9);
  Observations o = makeObservations(100, 0.0, rng);
  std::vector<int> clean;
  for (int i = 0; i < 100; ++i) {
    if (i % 2 == 0) o.pixels[i] += Eigen::Vector2d(300, -200);  // garbage outside the subset
    else clean.push_back(i);
  }
  RefinePoseOptions options;
  options.loss = RefineLoss::kSquared;
  Pose pose = perturbed(o.world_to_camera);
  refinePose(o.pixels, o.points, clean, testCamera(), options, &pose);
  EXPECT_LT((pose.t - o.world_to_camera.t).norm(), 1e-9);
}

TEST(RefinePose, LeavesThePoseAloneWithoutEnoughPointsInFront) {
  std::mt19937_64 rng(10);
  const Observations o = makeObservations(10, 0.0, rng);
  Pose behind = o.world_to_camera;
  behind.t.z() -= 100.0;  // every point now behind the camera
  const Pose before = behind;
  const RefinePoseSummary summary =
      refinePose(o.pixels, o.points, allIndices(o.pixels.size()), testCamera(), RefinePoseOptions{}, &behind);
  EXPECT_EQ(summary.iterations, 0);
  EXPECT_EQ(behind.t, before.t);
}

}  // namespace
}  // namespace ffloc
