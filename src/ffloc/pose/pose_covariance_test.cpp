#include "ffloc/pose/pose_covariance.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numeric>
#include <random>

#include "ffloc/core/error.h"
#include "ffloc/pose/refine_pose.h"

namespace ffloc {
namespace {

Intrinsics testCamera() { return {500, 520, 320, 240, 640, 480, {}}; }

Pose trueWorldToCamera() {
  Pose pose;
  pose.R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  pose.t = Eigen::Vector3d(0.3, -0.2, 1.5);
  return pose;
}

// Points seen in a window of `window` pixels square at the image centre, `near` to `far` deep.
struct Scene {
  std::vector<Eigen::Vector2d> pixels;  // exact projections
  std::vector<Eigen::Vector3d> points;
};

Scene makeScene(int count, double window, std::mt19937_64& rng, double near = 1, double far = 6) {
  const Intrinsics camera = testCamera();
  const Pose camera_to_world = trueWorldToCamera().inverse();
  std::uniform_real_distribution<double> u(camera.cx - window / 2, camera.cx + window / 2),
      v(camera.cy - window / 2, camera.cy + window / 2), depth(near, far);
  Scene scene;
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector2d pixel(u(rng), v(rng));
    scene.pixels.push_back(pixel);
    scene.points.push_back(camera_to_world * camera.backproject(pixel, depth(rng)));
  }
  return scene;
}

std::vector<int> allIndices(size_t n) {
  std::vector<int> indices(n);
  std::iota(indices.begin(), indices.end(), 0);
  return indices;
}

PoseCovarianceOptions fixedSigma(double sigma) {
  PoseCovarianceOptions options;
  options.pixel_sigma = sigma;
  return options;
}

// The prediction is what it claims: over many noise draws, the least-squares poses scatter about
// the truth as the covariance at the truth says, and the sigma estimated from one draw's
// residuals gives the noise back.
TEST(PoseCovariance, PredictsTheSpreadOfPosesOverNoiseDraws) {
  std::mt19937_64 rng(11);
  // Points at 5 to 6 units: the centre is far worse determined across the view than along it, so
  // a covariance left in camera axes would not match the world's.
  const Scene scene = makeScene(60, 640, rng, 5, 6);
  const std::vector<int> indices = allIndices(scene.pixels.size());
  const double noise_px = 1.5;
  const PoseCovariance predicted =
      estimatePoseCovariance(scene.pixels, scene.points, indices, testCamera(), trueWorldToCamera(), fixedSigma(noise_px));
  ASSERT_TRUE(predicted.valid);

  std::normal_distribution<double> noise(0, noise_px);
  RefinePoseOptions least_squares;
  least_squares.loss = RefineLoss::kSquared;
  const Pose truth = trueWorldToCamera().inverse();
  double centre_squared = 0, rotation_squared = 0, sigma_squared = 0;
  Eigen::Matrix3d centre_scatter = Eigen::Matrix3d::Zero();
  const int draws = 400;
  for (int draw = 0; draw < draws; ++draw) {
    std::vector<Eigen::Vector2d> noisy = scene.pixels;
    for (Eigen::Vector2d& pixel : noisy) pixel += Eigen::Vector2d(noise(rng), noise(rng));
    Pose fitted = trueWorldToCamera();
    refinePose(noisy, scene.points, indices, testCamera(), least_squares, &fitted);
    const Pose camera_to_world = fitted.inverse();
    const Eigen::Vector3d centre_error = camera_to_world.centre() - truth.centre();
    centre_scatter += centre_error * centre_error.transpose();
    centre_squared += centre_error.squaredNorm();
    rotation_squared += std::pow(rotationErrorDeg(camera_to_world, truth), 2);
    sigma_squared += std::pow(estimatePoseCovariance(noisy, scene.points, indices, testCamera(), fitted).residual_sigma_px, 2);
  }
  const double centre_rms = std::sqrt(centre_squared / draws), rotation_rms = std::sqrt(rotation_squared / draws);
  EXPECT_NEAR(predicted.centre_sigma / centre_rms, 1.0, 0.15) << predicted.centre_sigma << " vs " << centre_rms;
  EXPECT_NEAR(predicted.rotation_sigma_deg / rotation_rms, 1.0, 0.15) << predicted.rotation_sigma_deg << " vs " << rotation_rms;
  EXPECT_NEAR(std::sqrt(sigma_squared / draws), noise_px, 0.1 * noise_px);
  // Axis by axis in the world too: the centre's covariance is turned into world axes.
  for (int axis = 0; axis < 3; ++axis)
    EXPECT_NEAR(std::sqrt(predicted.centre_covariance(axis, axis) / (centre_scatter(axis, axis) / draws)), 1.0, 0.15)
        << "axis " << axis;
}

TEST(PoseCovariance, MorePairsAndWiderSpreadGiveSmallerSigma) {
  std::mt19937_64 rng(12);
  const Pose pose = trueWorldToCamera();
  auto sigmaOf = [&](int count, double window) {
    const Scene scene = makeScene(count, window, rng);
    return estimatePoseCovariance(scene.pixels, scene.points, allIndices(count), testCamera(), pose, fixedSigma(1.0));
  };
  const PoseCovariance few = sigmaOf(30, 480), many = sigmaOf(480, 480), patch = sigmaOf(480, 60);
  ASSERT_TRUE(few.valid && many.valid && patch.valid);
  // Sixteen times the pairs: about a quarter of the sigma.
  EXPECT_LT(many.centre_sigma, 0.4 * few.centre_sigma);
  EXPECT_LT(many.rotation_sigma_deg, 0.4 * few.rotation_sigma_deg);
  // The same pairs crowded into an eighth of the width: far worse determined.
  EXPECT_GT(patch.centre_sigma, 4 * many.centre_sigma);
  EXPECT_GT(patch.rotation_sigma_deg, 4 * many.rotation_sigma_deg);
}

TEST(PoseCovariance, ScalesWithThePixelSigma) {
  std::mt19937_64 rng(13);
  const Scene scene = makeScene(50, 640, rng);
  const std::vector<int> indices = allIndices(scene.pixels.size());
  const PoseCovariance one = estimatePoseCovariance(scene.pixels, scene.points, indices, testCamera(), trueWorldToCamera(), fixedSigma(1));
  const PoseCovariance three = estimatePoseCovariance(scene.pixels, scene.points, indices, testCamera(), trueWorldToCamera(), fixedSigma(3));
  EXPECT_NEAR(three.centre_sigma, 3 * one.centre_sigma, 1e-9 * one.centre_sigma);
  EXPECT_NEAR(three.rotation_sigma_deg, 3 * one.rotation_sigma_deg, 1e-9 * one.rotation_sigma_deg);
  // Exact pixels: the estimated noise, and with it the uncertainty, vanishes.
  const PoseCovariance estimated = estimatePoseCovariance(scene.pixels, scene.points, indices, testCamera(), trueWorldToCamera());
  EXPECT_TRUE(estimated.valid);
  EXPECT_LT(estimated.residual_sigma_px, 1e-9);
  EXPECT_LT(estimated.centre_sigma, 1e-9);
}

TEST(PoseCovariance, TooFewPairsOrPointsBehindGiveNoCovariance) {
  std::mt19937_64 rng(14);
  Scene scene = makeScene(5, 640, rng);
  const std::vector<int> three = {0, 1, 2};
  EXPECT_FALSE(estimatePoseCovariance(scene.pixels, scene.points, three, testCamera(), trueWorldToCamera()).valid);
  // Behind the camera the pair does not count: two of five left.
  const Pose camera_to_world = trueWorldToCamera().inverse();
  for (int i = 0; i < 3; ++i) scene.points[i] = camera_to_world * Eigen::Vector3d(0.1 * i, 0, -2);
  const PoseCovariance behind =
      estimatePoseCovariance(scene.pixels, scene.points, allIndices(5), testCamera(), trueWorldToCamera());
  EXPECT_FALSE(behind.valid);
  EXPECT_EQ(behind.pairs, 2);
}

TEST(PoseCovariance, InvalidPixelSigmaNamesTheField) {
  std::mt19937_64 rng(15);
  const Scene scene = makeScene(10, 640, rng);
  for (double sigma : {-1.0, std::nan("")}) {
    try {
      estimatePoseCovariance(scene.pixels, scene.points, allIndices(10), testCamera(), trueWorldToCamera(), fixedSigma(sigma));
      ADD_FAILURE() << "no error for " << sigma;
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("pixel_sigma:", 0), 0u) << e.what();
    }
  }
}

}  // namespace
}  // namespace ffloc
