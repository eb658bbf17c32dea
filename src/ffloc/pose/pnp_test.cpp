#include "ffloc/pose/pnp.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <limits>
#include <random>

#include "ffloc/core/error.h"

namespace ffloc {
namespace {

Intrinsics testCamera() { return {525, 525, 319.5, 239.5, 640, 480, {}}; }

struct SyntheticQuery {
  Pose camera_to_world;
  Correspondences correspondences;
  std::vector<bool> is_inlier;
};

// Pixels anywhere in the image at depths 1-5 m, with Gaussian pixel noise; a fraction of the
// pairs get a world point drawn uniformly from the box around the scene instead.
SyntheticQuery makeQuery(int count, double outlier_fraction, double noise_px, uint64_t seed) {
  std::mt19937_64 rng(seed);
  const Intrinsics camera = testCamera();
  std::normal_distribution<double> normal;
  SyntheticQuery q;
  q.camera_to_world.R = Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)).normalized().toRotationMatrix();
  q.camera_to_world.t = Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
  std::uniform_real_distribution<double> u(0, camera.width - 1), v(0, camera.height - 1), depth(1, 5), unit(0, 1);
  std::normal_distribution<double> noise(0, noise_px);
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector2d pixel(u(rng), v(rng));
    const Eigen::Vector3d point = q.camera_to_world * camera.backproject(pixel, depth(rng));
    q.correspondences.add(pixel + Eigen::Vector2d(noise(rng), noise(rng)), point, 3.0f);
    q.is_inlier.push_back(true);
  }
  Eigen::Vector3d low = q.correspondences.points[0], high = low;
  for (const Eigen::Vector3d& p : q.correspondences.points) {
    low = low.cwiseMin(p);
    high = high.cwiseMax(p);
  }
  for (int i = 0; i < count; ++i) {
    if (unit(rng) >= outlier_fraction) continue;
    q.correspondences.points[i] = low + (high - low).cwiseProduct(Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
    q.is_inlier[i] = false;
  }
  return q;
}

int countInliers(const SyntheticQuery& q) { return static_cast<int>(std::count(q.is_inlier.begin(), q.is_inlier.end(), true)); }

class BothSolvers : public ::testing::TestWithParam<PnpSolver> {
 protected:
  PnpOptions options() const {
    PnpOptions o;
    o.solver = GetParam();
    return o;
  }
};

TEST_P(BothSolvers, RecoversThePoseWithHalfOutliersAndPixelNoise) {
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    const SyntheticQuery q = makeQuery(2000, 0.5, 1.0, seed);
    const PnpResult result = estimatePose(q.correspondences, testCamera(), options());
    ASSERT_TRUE(result.ok()) << toString(result.status);
    EXPECT_LT(translationError(result.camera_to_world, q.camera_to_world), 0.01) << "seed " << seed;
    EXPECT_LT(rotationErrorDeg(result.camera_to_world, q.camera_to_world), 0.1) << "seed " << seed;
    EXPECT_EQ(result.used_correspondences, 2000);
    // Every true inlier (1 px noise against an 8 px threshold), and hardly any outlier by chance.
    EXPECT_GE(result.inliers, countInliers(q));
    EXPECT_LE(result.inliers, countInliers(q) + 10);
    EXPECT_GE(result.seconds, 0.0);
  }
}

TEST_P(BothSolvers, WithoutRefinementTheRobustEstimateIsStillClose) {
  const SyntheticQuery q = makeQuery(2000, 0.5, 1.0, 6);
  PnpOptions unrefined = options();
  unrefined.refine = false;
  const PnpResult result = estimatePose(q.correspondences, testCamera(), unrefined);
  ASSERT_TRUE(result.ok());
  EXPECT_LT(translationError(result.camera_to_world, q.camera_to_world), 0.03);
  EXPECT_LT(rotationErrorDeg(result.camera_to_world, q.camera_to_world), 0.3);
}

TEST_P(BothSolvers, DropsLowConfidencePairsBeforeEstimating) {
  SyntheticQuery q = makeQuery(1000, 0.5, 1.0, 11);
  // The outliers get C = 1.2 (below the paper's 1.5), one inlier NaN: only inliers are used.
  int kept = 0;
  for (size_t i = 0; i < q.correspondences.size(); ++i) {
    if (!q.is_inlier[i]) q.correspondences.confidences[i] = 1.2f;
    else if (kept++ == 0) q.correspondences.confidences[i] = std::numeric_limits<float>::quiet_NaN();
  }
  const PnpResult result = estimatePose(q.correspondences, testCamera(), options());
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result.used_correspondences, countInliers(q) - 1);
  EXPECT_EQ(result.inliers, result.used_correspondences);
  EXPECT_LT(translationError(result.camera_to_world, q.camera_to_world), 0.01);

  PnpOptions permissive = options();
  permissive.confidence_threshold = 1.0f;
  EXPECT_EQ(estimatePose(q.correspondences, testCamera(), permissive).used_correspondences, 999);
}

TEST_P(BothSolvers, SubsamplesToTheCap) {
  const SyntheticQuery q = makeQuery(8000, 0.3, 1.0, 12);
  const PnpResult capped = estimatePose(q.correspondences, testCamera(), options());
  ASSERT_TRUE(capped.ok());
  EXPECT_EQ(capped.used_correspondences, 5000);
  EXPECT_LE(capped.inliers, 5000);

  PnpOptions small = options();
  small.max_correspondences = 300;
  const PnpResult few = estimatePose(q.correspondences, testCamera(), small);
  ASSERT_TRUE(few.ok());
  EXPECT_EQ(few.used_correspondences, 300);
  EXPECT_LE(few.inliers, 300);
  EXPECT_GT(few.inliers, 150);  // about 70% of 300 are inliers
  EXPECT_LT(translationError(few.camera_to_world, q.camera_to_world), 0.03);
}

TEST_P(BothSolvers, TooFewPairsIsAStatus) {
  const SyntheticQuery q = makeQuery(10, 0.0, 0.0, 13);
  EXPECT_EQ(estimatePose(Correspondences{}, testCamera(), options()).status, PnpStatus::kTooFewCorrespondences);

  Correspondences three;
  for (int i = 0; i < 3; ++i) three.add(q.correspondences.pixels[i], q.correspondences.points[i], 3.0f);
  const PnpResult result = estimatePose(three, testCamera(), options());
  EXPECT_EQ(result.status, PnpStatus::kTooFewCorrespondences);
  EXPECT_EQ(result.used_correspondences, 3);

  // Three pairs above the threshold: too few when the threshold is strict; by default the most
  // confident pairs (all ten) are used instead.
  Correspondences filtered = q.correspondences;
  for (size_t i = 3; i < filtered.size(); ++i) filtered.confidences[i] = 1.0f;
  PnpOptions strict = options();
  strict.min_correspondences = 0;
  EXPECT_EQ(estimatePose(filtered, testCamera(), strict).status, PnpStatus::kTooFewCorrespondences);
  EXPECT_EQ(estimatePose(filtered, testCamera(), options()).used_correspondences, 10);
}

TEST_P(BothSolvers, CollinearPointsGiveNoPose) {
  const Intrinsics camera = testCamera();
  Correspondences line;
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d point(-1.0 + 0.01 * i, 0.3 - 0.002 * i, 3.0 + 0.005 * i);
    line.add(camera.project(point), point, 3.0f);
  }
  const PnpResult result = estimatePose(line, camera, options());
  EXPECT_FALSE(result.ok()) << toString(result.status);
}

TEST_P(BothSolvers, AllOutliersGiveNoPose) {
  // With 5000 pairs a random pose collects ~13 inliers by chance: more than min_inliers, so only
  // the chance-support bound keeps pure noise from coming back as a pose.
  for (int count : {300, 5000}) {
    std::mt19937_64 rng(14);
    std::uniform_real_distribution<double> u(0, 639), v(0, 479), coordinate(-3, 3);
    Correspondences noise;
    for (int i = 0; i < count; ++i)
      noise.add({u(rng), v(rng)}, {coordinate(rng), coordinate(rng), coordinate(rng)}, 3.0f);
    const PnpResult result = estimatePose(noise, testCamera(), options());
    EXPECT_FALSE(result.ok()) << count << " pairs: " << toString(result.status) << " with " << result.inliers
                              << " inliers";
    EXPECT_EQ(result.used_correspondences, count);
  }
}

INSTANTIATE_TEST_SUITE_P(Pnp, BothSolvers, ::testing::Values(PnpSolver::kLoRansac, PnpSolver::kOpenCvUsac),
                         [](const ::testing::TestParamInfo<PnpSolver>& info) {
                           return info.param == PnpSolver::kLoRansac ? "LoRansac" : "OpenCvUsac";
                         });

TEST(Pnp, LoRansacIsDeterministicForASeed) {
  const SyntheticQuery q = makeQuery(8000, 0.6, 2.0, 15);
  PnpOptions options;
  options.solver = PnpSolver::kLoRansac;
  options.seed = 42;
  const PnpResult a = estimatePose(q.correspondences, testCamera(), options);
  const PnpResult b = estimatePose(q.correspondences, testCamera(), options);
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a.camera_to_world.R, b.camera_to_world.R);
  EXPECT_EQ(a.camera_to_world.t, b.camera_to_world.t);
  EXPECT_EQ(a.inliers, b.inliers);

  // Another seed draws another subset, so the pose differs in the last digits but is as good.
  options.seed = 43;
  const PnpResult c = estimatePose(q.correspondences, testCamera(), options);
  ASSERT_TRUE(c.ok());
  EXPECT_NE(c.camera_to_world.t, a.camera_to_world.t);
  EXPECT_LT(translationError(c.camera_to_world, q.camera_to_world), 0.01);
}

TEST(Pnp, TooFewInliersIsAStatus) {
  const SyntheticQuery q = makeQuery(500, 0.0, 0.5, 16);
  PnpOptions options;
  options.min_inliers = 501;
  const PnpResult result = estimatePose(q.correspondences, testCamera(), options);
  EXPECT_EQ(result.status, PnpStatus::kTooFewInliers);
  EXPECT_EQ(result.inliers, 500);
  EXPECT_EQ(result.required_inliers, 501);

  // In a 16 x 12 image every pair lies within 8 px of any projection: chance alone explains all
  // 500, so the bound passes their count.
  Intrinsics tiny = testCamera();
  tiny.width = 16;
  tiny.height = 12;
  const PnpResult by_chance = estimatePose(q.correspondences, tiny, PnpOptions{});
  EXPECT_EQ(by_chance.status, PnpStatus::kTooFewInliers);
  EXPECT_GT(by_chance.required_inliers, 500);
}

TEST(Pnp, BadInputThrowsInputErrorNamingTheField) {
  const SyntheticQuery q = makeQuery(50, 0.0, 0.0, 17);
  Correspondences mismatched = q.correspondences;
  mismatched.confidences.pop_back();
  EXPECT_THROW(estimatePose(mismatched, testCamera(), {}), InputError);

  Intrinsics no_focal = testCamera();
  no_focal.fx = 0;
  try {
    estimatePose(q.correspondences, no_focal, {});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("fx"), std::string::npos) << e.what();
  }

  PnpOptions bad;
  bad.inlier_threshold_px = -1;
  try {
    estimatePose(q.correspondences, testCamera(), bad);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("inlier_threshold_px"), std::string::npos) << e.what();
  }
}

TEST(Pnp, SolverNamesRoundTrip) {
  for (PnpSolver solver : {PnpSolver::kLoRansac, PnpSolver::kOpenCvUsac})
    EXPECT_EQ(parsePnpSolver(toString(solver)), solver);
  EXPECT_THROW(parsePnpSolver("poselib"), InputError);
  EXPECT_STREQ(toString(PnpStatus::kTooFewInliers), "too few inliers");
}

}  // namespace
}  // namespace ffloc
