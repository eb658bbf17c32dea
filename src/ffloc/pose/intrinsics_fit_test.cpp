#include "ffloc/pose/intrinsics_fit.h"

#include "ffloc/pose/refine_pose.h"
#include "ffloc/pose/reprojection.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <numeric>
#include <random>

namespace ffloc {
namespace {

Intrinsics givenCamera() { return {500, 500, 320, 240, 640, 480, {}}; }

Pose worldToCamera() {
  Pose pose;
  pose.R = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, -2, 1).normalized()).toRotationMatrix();
  pose.t = Eigen::Vector3d(0.2, 0.1, 0.5);
  return pose;
}

struct Pairs {
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
  std::vector<int> indices;
};

// Pixels seen by a camera with the intrinsics `truth`, with `noise_px` of noise, of points `near`
// to `far` deep.
Pairs observe(const Intrinsics& truth, double near, double far, uint64_t seed, double noise_px = 0.5) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 640), v(0, 480), depth(near, far);
  std::normal_distribution<double> noise(0, noise_px);
  const Pose camera_to_world = worldToCamera().inverse();
  Pairs pairs;
  for (int i = 0; i < 300; ++i) {
    const Eigen::Vector2d pixel(u(rng), v(rng));
    pairs.points.push_back(camera_to_world * truth.backproject(pixel, depth(rng)));
    pairs.pixels.push_back(pixel + Eigen::Vector2d(noise(rng), noise(rng)));
  }
  pairs.indices.resize(pairs.pixels.size());
  std::iota(pairs.indices.begin(), pairs.indices.end(), 0);
  return pairs;
}

Pairs observe(double true_scale, double near, double far, uint64_t seed, double noise_px = 0.5) {
  Intrinsics truth = givenCamera();
  truth.fx *= true_scale;
  truth.fy *= true_scale;
  return observe(truth, near, far, seed, noise_px);
}

// `pairs` with `count` pairs of random pixels and points added: matches that are simply wrong.
Pairs withOutliers(Pairs pairs, int count, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 640), v(0, 480), depth(1, 6);
  const Pose camera_to_world = worldToCamera().inverse();
  for (int i = 0; i < count; ++i) {
    pairs.indices.push_back(static_cast<int>(pairs.pixels.size()));
    pairs.pixels.emplace_back(u(rng), v(rng));
    pairs.points.push_back(camera_to_world * givenCamera().backproject({u(rng), v(rng)}, depth(rng)));
  }
  return pairs;
}

// The pose that best fits `pairs` under the intrinsics given (a Cauchy loss, from the true pose),
// and its inliers (8 px): what PnP hands the verdict when the query's intrinsics are wrong.
std::pair<Pose, std::vector<int>> poseWithTheGivenIntrinsics(const Pairs& pairs) {
  Pose pose = worldToCamera();
  RefinePoseOptions cauchy;
  cauchy.loss_scale_px = 4;
  refinePose(pairs.pixels, pairs.points, pairs.indices, givenCamera(), cauchy, &pose);
  return {pose, findInliers(pairs.pixels, pairs.points, givenCamera(), pose, 8)};
}

// Started at the pose and focal length given, the fit finds the focal length the pixels were
// seen with, and says how well the depth relief determines it.
TEST(FocalFit, RecoversTheFocalLengthThePixelsWereSeenWith) {
  for (const double true_scale : {1.0, 0.6, 1.7}) {
    SCOPED_TRACE(true_scale);
    const Pairs pairs = observe(true_scale, 1, 6, 7);
    const FactorFit fit = fitFocalScale(pairs.pixels, pairs.points, pairs.indices, givenCamera(), worldToCamera());
    ASSERT_TRUE(fit.valid);
    EXPECT_NEAR(fit.factor, true_scale, 0.01 * true_scale);
    EXPECT_GT(fit.log_sigma, 0);
    EXPECT_LT(fit.log_sigma, 0.01);
  }
}

// fy 1.25 times what the pixels were seen with, fx right: the aspect fit finds the ratio fy / fx
// (0.8 of the one given; the product fx fy is off too, which it keeps, so within 2 %) and says how
// sure it is.
TEST(FocalFit, TheAspectFitFindsARatioOfFocalLengthsTheCommonScaleMisses) {
  Intrinsics given = givenCamera();
  given.fy *= 1.25;
  const Pairs pairs = observe(givenCamera(), 1, 6, 7);
  const FactorFit aspect = fitFocalAspect(pairs.pixels, pairs.points, pairs.indices, given, worldToCamera());
  ASSERT_TRUE(aspect.valid);
  EXPECT_NEAR(aspect.factor, 0.8, 0.016);
  EXPECT_GT(aspect.log_sigma, 0);
  EXPECT_LT(aspect.log_sigma, 0.01);
  const FactorFit right = fitFocalAspect(pairs.pixels, pairs.points, pairs.indices, givenCamera(), worldToCamera());
  ASSERT_TRUE(right.valid);
  EXPECT_NEAR(right.factor, 1.0, 3 * right.log_sigma);
}

// A pose estimated with a focal length 1.33 times the true one (3 px of noise, 100 wrong pairs
// among 400): its inliers (8 px) are the pairs that focal length explains, and a fit over them
// alone is drawn back towards it. With the threshold, the pairs the fitted focal length and pose
// explain join in, round by round, the wrong ones staying out, and the fit reaches the true
// focal length.
TEST(FocalFit, RefitOnThePairsItExplainsEscapesTheInliersOfTheWrongFocalLength) {
  const double true_scale = 0.75;
  const Pairs pairs = withOutliers(observe(true_scale, 1, 6, 11, 3), 100, 21);
  const auto [pose, inliers] = poseWithTheGivenIntrinsics(pairs);
  ASSERT_GT(inliers.size(), 20u);
  ASSERT_LT(inliers.size(), pairs.pixels.size());
  const FactorFit once = fitFocalScale(pairs.pixels, pairs.points, inliers, givenCamera(), pose);
  const FactorFit refit = fitFocalScale(pairs.pixels, pairs.points, inliers, givenCamera(), pose, 8);
  ASSERT_TRUE(once.valid);
  ASSERT_TRUE(refit.valid);
  EXPECT_NEAR(refit.factor, true_scale, 0.01 * true_scale);
  EXPECT_GT(std::abs(once.factor - true_scale), 0.05 * true_scale);
}

// Points of a thin, far slab: a longer focal length and a camera moved back see nearly the same
// pixels, so the fit's predicted uncertainty is large, and the verdict cannot blame the focal length.
TEST(FocalFit, AFarThinSlabLeavesTheFocalLengthUndetermined) {
  const Pairs far = observe(1.0, 50, 50.05, 8);
  const FactorFit fit = fitFocalScale(far.pixels, far.points, far.indices, givenCamera(), worldToCamera());
  const Pairs deep = observe(1.0, 1, 6, 8);
  const FactorFit deep_fit = fitFocalScale(deep.pixels, deep.points, deep.indices, givenCamera(), worldToCamera());
  ASSERT_TRUE(deep_fit.valid);
  EXPECT_TRUE(!fit.valid || fit.log_sigma > 50 * deep_fit.log_sigma);
}

TEST(FocalFit, TooFewPairsGiveNoFit) {
  Pairs pairs = observe(1.0, 1, 6, 9);
  pairs.indices.resize(4);
  EXPECT_FALSE(fitFocalScale(pairs.pixels, pairs.points, pairs.indices, givenCamera(), worldToCamera()).valid);
}

// Started at the principal point given, the fit finds the one the pixels were seen with; given
// the right one, it stays within a pixel and a few predicted sigma of it.
TEST(PrincipalPointFit, RecoversThePrincipalPointThePixelsWereSeenWith) {
  Intrinsics truth = givenCamera();
  truth.cx += 30;
  truth.cy -= 20;
  const Pairs moved = observe(truth, 1, 6, 10);
  const PrincipalPointFit fit = fitPrincipalPoint(moved.pixels, moved.points, moved.indices, givenCamera(), worldToCamera());
  ASSERT_TRUE(fit.valid);
  EXPECT_NEAR(fit.shift_px.x(), 30, 1.5);
  EXPECT_NEAR(fit.shift_px.y(), -20, 1.5);
  EXPECT_GT(fit.significance, 20);

  const Pairs right = observe(givenCamera(), 1, 6, 10);
  const PrincipalPointFit same = fitPrincipalPoint(right.pixels, right.points, right.indices, givenCamera(), worldToCamera());
  ASSERT_TRUE(same.valid);
  EXPECT_LT(same.shift_px.norm(), 1.5);
  EXPECT_LT(same.significance, 4);
}

// The same for a principal point 60 px (0.12 focal lengths) from the one given, 3 px of noise:
// the inliers of the pose estimated with the given one fit a shift drawn back towards it, the
// refit the shift.
TEST(PrincipalPointFit, RefitOnThePairsItExplainsEscapesTheInliersOfTheWrongPrincipalPoint) {
  Intrinsics truth = givenCamera();
  truth.cx += 60;
  const Pairs pairs = withOutliers(observe(truth, 1, 6, 13, 3), 100, 22);
  const auto [pose, inliers] = poseWithTheGivenIntrinsics(pairs);
  ASSERT_GT(inliers.size(), 20u);
  ASSERT_LT(inliers.size(), pairs.pixels.size());
  const PrincipalPointFit once = fitPrincipalPoint(pairs.pixels, pairs.points, inliers, givenCamera(), pose);
  const PrincipalPointFit refit = fitPrincipalPoint(pairs.pixels, pairs.points, inliers, givenCamera(), pose, 8);
  ASSERT_TRUE(once.valid);
  ASSERT_TRUE(refit.valid);
  EXPECT_LT(once.shift_px.x(), 50);
  EXPECT_NEAR(refit.shift_px.x(), 60, 3);
  EXPECT_NEAR(refit.shift_px.y(), 0, 3);
}

// A narrow view of a far, thin slab: moving the principal point and turning the camera move the
// pixels alike, so the shift is not significant however large.
TEST(PrincipalPointFit, ANarrowViewLeavesThePrincipalPointUndetermined) {
  Intrinsics telephoto = givenCamera();
  telephoto.fx = telephoto.fy = 5000;
  Intrinsics truth = telephoto;
  truth.cx += 30;
  const Pairs far = observe(truth, 50, 50.05, 11);
  const PrincipalPointFit fit = fitPrincipalPoint(far.pixels, far.points, far.indices, telephoto, worldToCamera());
  EXPECT_TRUE(!fit.valid || fit.significance < 3);
}

TEST(PrincipalPointFit, TooFewPairsGiveNoFit) {
  Pairs pairs = observe(givenCamera(), 1, 6, 12);
  pairs.indices.resize(4);
  EXPECT_FALSE(fitPrincipalPoint(pairs.pixels, pairs.points, pairs.indices, givenCamera(), worldToCamera()).valid);
}

}  // namespace
}  // namespace ffloc
