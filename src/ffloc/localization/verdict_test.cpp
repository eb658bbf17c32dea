#include "ffloc/localization/verdict.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "ffloc/core/error.h"
#include "ffloc/localization/localizer.h"

namespace ffloc {
namespace {

PnpResult success() {
  PnpResult pose;
  pose.status = PnpStatus::kSuccess;
  pose.inliers = 300;
  pose.used_correspondences = 600;
  return pose;
}

PoseEvidence strong() {
  PoseEvidence e;
  e.inliers = 300;
  e.used_correspondences = 600;
  e.inlier_ratio = 0.5;
  e.inlier_spread = 0.5;
  e.agreement_translation = 0.002;
  e.agreement_rotation_deg = 0.1;
  e.agreement_distance = 0.004;
  e.residual_sigma_px = 1.0;
  e.predicted_centre_sigma = 0.01;
  e.predicted_centre_sigma_relative = 0.004;
  e.predicted_rotation_sigma_deg = 0.3;
  return e;
}

// The verdict on strong() evidence after `change`.
template <typename Change>
PoseVerdict judgedStrong(Change change, const VerdictOptions& rule = {}, bool metric = true) {
  PoseEvidence e = strong();
  change(e);
  return judgePose(e, success(), metric, rule);
}

TEST(Verdict, EachTestCanMakeAPoseUncertain) {
  const VerdictOptions rule;
  EXPECT_EQ(judgePose(strong(), success(), true, rule).status, PoseStatus::kLocalized);

  auto judged = [&](auto change, bool metric = true) { return judgedStrong(change, rule, metric); };
  EXPECT_EQ(judged([](PoseEvidence& e) { e.inliers = 11; }).reason, "11 inliers, fewer than 12");
  EXPECT_EQ(judged([](PoseEvidence& e) { e.inlier_ratio = 0.09; }).status, PoseStatus::kUncertain);
  EXPECT_EQ(judged([](PoseEvidence& e) { e.inlier_spread = 0.09; }).reason, "inliers cover too little of the image");
  EXPECT_EQ(judged([](PoseEvidence& e) { e.agreement_rotation_deg = 9; }).reason, "a second estimate disagrees");
  EXPECT_EQ(judged([](PoseEvidence& e) { e.agreement_translation = 0.06; }).status, PoseStatus::kUncertain);
  // 8 cm apart: too far in a metric map, not judged in metres in one of arbitrary units.
  EXPECT_EQ(judged([](PoseEvidence& e) { e.agreement_distance = 0.08; }).status, PoseStatus::kUncertain);
  EXPECT_EQ(judged([](PoseEvidence& e) { e.agreement_distance = 0.08; }, false).status, PoseStatus::kLocalized);
  // A centre predicted 12 cm uncertain: too uncertain in a metric map, not judged in metres in one
  // of arbitrary units.
  EXPECT_EQ(judged([](PoseEvidence& e) { e.predicted_centre_sigma = 0.12; }).reason,
            "the inliers leave the pose too uncertain");
  EXPECT_EQ(judged([](PoseEvidence& e) { e.predicted_centre_sigma = 0.12; }, false).status, PoseStatus::kLocalized);
}

// Inliers that fit another focal length than the one given: the query's intrinsics are wrong, and
// its pose slid along the optical axis. A deviation past 1.2x (or 1/1.2x) and 6 predicted
// standard deviations counts, one past 15 % at 8 (synthetic queries given 1.2 times their focal
// length fit 0.84-0.86 at 9-28 sigma), and one past 5 % at 30 (redkitchen's frames given its
// depth camera's 585 px instead of 525 fit 0.90 at 170 sigma, 22 cm off).
TEST(Verdict, AFocalLengthTheInliersDoNotFitMakesThePoseUncertain) {
  auto judged = [](double scale, double log_sigma, const VerdictOptions& rule = {}) {
    return judgedStrong([&](PoseEvidence& e) { e.focal_scale = scale; e.focal_scale_log_sigma = log_sigma; }, rule);
  };
  EXPECT_EQ(judged(1.0, 0.001).status, PoseStatus::kLocalized);
  EXPECT_EQ(judged(1.14, 0.01).status, PoseStatus::kLocalized);  // 13 sigma: within 15 % and not certain
  EXPECT_EQ(judged(0.85, 0.01).status, PoseStatus::kUncertain);  // 16 sigma past 15 %
  EXPECT_EQ(judged(0.85, 0.025).status, PoseStatus::kLocalized);  // 6.5 sigma: within 1.2x, not 8 sigma
  EXPECT_EQ(judged(1.17, 0.019).status, PoseStatus::kUncertain);  // 8.3 sigma
  EXPECT_EQ(judged(0.8, 0.01).status, PoseStatus::kUncertain);   // below 1/1.2
  EXPECT_EQ(judged(1.3, 0.05).status, PoseStatus::kLocalized);    // 5.2 sigma
  EXPECT_EQ(judged(1.3, 0.04).status, PoseStatus::kUncertain);    // 6.6 sigma
  EXPECT_EQ(judged(1.6, 0.02).reason,
            "the correspondences fit a focal length 1.6 times the one given: check the query's intrinsics");
  EXPECT_EQ(judged(0.6, 0.02).status, PoseStatus::kUncertain);
  EXPECT_EQ(judged(1.6, 0.5).status, PoseStatus::kLocalized);  // a far plane: the focal length is not determined
  EXPECT_EQ(judged(1.6, std::numeric_limits<double>::infinity()).status, PoseStatus::kLocalized);
  EXPECT_EQ(judged(0.9, 0.0006).status, PoseStatus::kUncertain);
  EXPECT_EQ(judged(0.9, 0.005).status, PoseStatus::kLocalized);    // 21 sigma: what right poses reach
  EXPECT_EQ(judged(1.04, 0.0006).status, PoseStatus::kLocalized);  // within 5 %
  VerdictOptions off;
  off.max_focal_deviation = off.max_moderate_focal_deviation = off.max_certain_focal_deviation =
      std::numeric_limits<double>::infinity();
  EXPECT_EQ(judged(3, 0.01, off).status, PoseStatus::kLocalized);
}

// Inliers that fit another ratio fy / fx than the one given (a query given fy 700 where fx and fy
// are 525, 0.7 m off): past 12 % at 10 sigma, or past 7 % at 30; what right poses fit does not
// (redkitchen's frame 840, 10 % at 19.5 sigma; frame 644, 4.5 % at 29).
TEST(Verdict, ARatioOfFocalLengthsTheInliersDoNotFitMakesThePoseUncertain) {
  auto judged = [](double aspect, double log_sigma) {
    return judgedStrong([&](PoseEvidence& e) { e.focal_aspect = aspect; e.focal_aspect_log_sigma = log_sigma; }, {});
  };
  EXPECT_EQ(judged(1.0, 0.001).status, PoseStatus::kLocalized);
  EXPECT_EQ(judged(1.105, 0.00512).status, PoseStatus::kLocalized);  // frame 840
  EXPECT_EQ(judged(1.046, 0.00155).status, PoseStatus::kLocalized);  // frame 644
  EXPECT_EQ(judged(0.85, 0.01).reason,
            "the correspondences fit a ratio fy / fx 0.85 times the one given: check the query's intrinsics");
  EXPECT_EQ(judged(0.85, 0.02).status, PoseStatus::kLocalized);   // 8 sigma
  EXPECT_EQ(judged(0.92, 0.002).status, PoseStatus::kUncertain);  // 8 % at 42 sigma
  EXPECT_EQ(judged(0.95, 0.001).status, PoseStatus::kLocalized);  // 5 %: within the certain tier
  EXPECT_EQ(judged(0.85, std::numeric_limits<double>::infinity()).status, PoseStatus::kLocalized);
}

// Another focal length whose pose gathers clearly more of the pairs: FastForward's queries given
// 0.8 times theirs (found by an outside probe, `localized` 0.3-0.76 m off).
TEST(Verdict, AFocalLengthWithMoreInliersMakesThePoseUncertain) {
  auto judged = [](double factor, double gain) {
    return judgedStrong([&](PoseEvidence& e) { e.focal_scan_factor = factor; e.focal_scan_inlier_gain = gain; }, {});
  };
  EXPECT_EQ(judged(1.3, 0.9).status, PoseStatus::kLocalized);
  EXPECT_EQ(judged(1.2, 1.21).status, PoseStatus::kLocalized);  // the most a right pose of redkitchen had
  EXPECT_EQ(judged(1.2, 1.6).reason,
            "a focal length 1.2 times the one given gives 1.6 times the inliers: check the query's intrinsics");
  EXPECT_EQ(judged(-1, -1).status, PoseStatus::kLocalized);  // no scan
}

// Inliers that fit another principal point: far off and significant, or a little off and
// certain, makes the pose uncertain; what right poses fit does not.
TEST(Verdict, APrincipalPointTheInliersDoNotFitMakesThePoseUncertain) {
  auto judged = [](double shift, double significance, const VerdictOptions& rule = {}) {
    return judgedStrong(
        [&](PoseEvidence& e) { e.principal_point_shift = shift; e.principal_point_shift_significance = significance; },
        rule);
  };
  EXPECT_EQ(judged(0.0, 0.0).status, PoseStatus::kLocalized);
  EXPECT_EQ(judged(0.26, 483).reason,
            "the correspondences fit a principal point 0.26 focal lengths from the one given: check the query's "
            "intrinsics");
  EXPECT_EQ(judged(0.12, 9).status, PoseStatus::kUncertain);
  EXPECT_EQ(judged(0.12, 5).status, PoseStatus::kLocalized);   // a narrow view: not determined
  EXPECT_EQ(judged(0.052, 289).status, PoseStatus::kUncertain);  // Strecha fountain, 5 % of the width off
  EXPECT_EQ(judged(0.07, 25).status, PoseStatus::kLocalized);  // redkitchen's nominal intrinsics
  EXPECT_EQ(judged(0.03, 300).status, PoseStatus::kLocalized);
  VerdictOptions off;
  off.max_principal_point_shift = off.max_certain_principal_point_shift = std::numeric_limits<double>::infinity();
  EXPECT_EQ(judged(0.5, 500, off).status, PoseStatus::kLocalized);
}

// The predicted-uncertainty tests (by default only the centre's in metres) each reject a pose when set.
TEST(Verdict, PredictedUncertaintyTestsRejectWhenSet) {
  EXPECT_EQ(judgePose(strong(), success(), true, VerdictOptions{}).status, PoseStatus::kLocalized);
  VerdictOptions rule;
  rule.max_centre_sigma_relative = 0.015;
  rule.max_centre_sigma_m = 0.075;
  rule.max_rotation_sigma_deg = 1.0;
  auto judged = [&](auto change, bool metric = true) {
    PoseEvidence e = strong();
    change(e);
    return judgePose(e, success(), metric, rule);
  };
  EXPECT_EQ(judged([](PoseEvidence&) {}).status, PoseStatus::kLocalized);
  EXPECT_EQ(judged([](PoseEvidence& e) { e.predicted_rotation_sigma_deg = 1.5; }).reason,
            "the inliers leave the pose too uncertain");
  EXPECT_EQ(judged([](PoseEvidence& e) { e.predicted_centre_sigma_relative = 0.02; }).status, PoseStatus::kUncertain);
  // Inliers that determine no pose at all (J^T J singular).
  EXPECT_EQ(judged([](PoseEvidence& e) { e.predicted_rotation_sigma_deg = std::numeric_limits<double>::infinity(); }).status,
            PoseStatus::kUncertain);
  // A predicted 20 cm: too uncertain in a metric map, not judged in metres in one of arbitrary units.
  EXPECT_EQ(judged([](PoseEvidence& e) { e.predicted_centre_sigma = 0.2; }).status, PoseStatus::kUncertain);
  EXPECT_EQ(judged([](PoseEvidence& e) { e.predicted_centre_sigma = 0.2; }, false).status, PoseStatus::kLocalized);
}

// A method whose errors run larger than its inliers predict (FastForward) has its prediction
// scaled before the rule reads it: a centre predicted at 4 cm passes at scale 1 and not at 3.5.
TEST(Verdict, ScaledUncertaintyIsJudgedAsScaled) {
  PoseEvidence e = strong();
  e.predicted_centre_sigma = 0.04;
  e.focal_scale = 1.05;
  e.focal_scale_log_sigma = 0.01;
  EXPECT_EQ(judgePose(e, success(), true, VerdictOptions{}).status, PoseStatus::kLocalized);
  scalePredictedUncertainty(e, 3.5);
  EXPECT_DOUBLE_EQ(e.predicted_centre_sigma, 0.14);
  EXPECT_DOUBLE_EQ(e.predicted_centre_sigma_relative, 0.004 * 3.5);
  EXPECT_DOUBLE_EQ(e.predicted_rotation_sigma_deg, 0.3 * 3.5);
  EXPECT_DOUBLE_EQ(e.focal_scale_log_sigma, 0.01);  // the focal test's sigma is judged as measured
  EXPECT_EQ(judgePose(e, success(), true, VerdictOptions{}).reason, "the inliers leave the pose too uncertain");
  // Without a pose there is nothing to scale: "none" stays negative.
  PoseEvidence none;
  scalePredictedUncertainty(none, 3.5);
  EXPECT_EQ(none.predicted_centre_sigma, -1);
  EXPECT_EQ(none.predicted_rotation_sigma_deg, -1);
  // A scale that would make a measured uncertainty vanish or flip is refused.
  for (double bad : {0.0, -1.0, std::nan(""), std::numeric_limits<double>::infinity()})
    EXPECT_THROW(scalePredictedUncertainty(e, bad), std::invalid_argument) << bad;
}

// A half-sample estimate that fails says the pairs are few, not that they disagree; the method's
// own second estimate (FastForward's second reference frame) failing does count.
TEST(Verdict, AFailedSecondEstimateCountsOnlyWhenIndependent) {
  const double inf = std::numeric_limits<double>::infinity();
  PoseEvidence e = strong();
  e.agreement_translation = e.agreement_rotation_deg = e.agreement_distance = inf;
  VerdictOptions rule;
  EXPECT_EQ(judgePose(e, success(), true, rule).reason, "too few pairs for a second estimate");
  rule.require_agreement = false;
  EXPECT_EQ(judgePose(e, success(), true, rule).status, PoseStatus::kLocalized);
  e.independent_second_estimate = true;
  EXPECT_EQ(judgePose(e, success(), true, VerdictOptions{}).reason, "the second reference frame gives no pose");
}

TEST(Verdict, NoPoseIsFailedAndSaysWhy) {
  PnpResult pose;
  pose.status = PnpStatus::kTooFewCorrespondences;
  const PoseVerdict verdict = judgePose(PoseEvidence{}, pose, true, VerdictOptions{});
  EXPECT_EQ(verdict.status, PoseStatus::kFailed);
  EXPECT_EQ(verdict.reason, "no pose: too few correspondences");
  // "too few inliers" beside "192 inliers of 192" read as a contradiction.
  pose.status = PnpStatus::kTooFewInliers;
  pose.inliers = 192;
  pose.required_inliers = 250;
  EXPECT_EQ(judgePose(PoseEvidence{}, pose, true, VerdictOptions{}).reason, "no pose: too few inliers (192, 250 needed)");
  pose.status = PnpStatus::kNoModel;  // said "no pose: no model", read as a missing network
  EXPECT_EQ(judgePose(PoseEvidence{}, pose, true, VerdictOptions{}).reason,
            "no pose: RANSAC found none the correspondences agree on (or only a degenerate one)");
}

TEST(Verdict, OptionsOutOfRangeNameTheField) {
  auto errorOf = [](auto change) {
    VerdictOptions rule;
    change(rule);
    try {
      rule.check();
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(errorOf([](VerdictOptions& r) { r.min_inliers = -1; }).rfind("min_inliers:", 0), 0u);
  EXPECT_EQ(errorOf([](VerdictOptions& r) { r.min_inlier_spread = 2; }).rfind("min_inlier_spread:", 0), 0u);
  EXPECT_EQ(errorOf([](VerdictOptions& r) { r.max_agreement_rotation_deg = std::nan(""); }).rfind("max_agreement_rotation_deg:", 0), 0u);
  EXPECT_EQ(errorOf([](VerdictOptions& r) { r.max_focal_scan_gain = 0.5; }).rfind("max_focal_scan_gain:", 0), 0u);
  EXPECT_EQ(errorOf([](VerdictOptions&) {}), "");
}

// 640 x 480, 500 px focal length, principal point at the centre.
Intrinsics vgaCamera() { return {500, 500, 320, 240, 640, 480, {}}; }

// Spread is measured on the pairs PnP chose from: a pose held by one corner of the image covers
// one cell of the 8 x 8 grid.
TEST(Verdict, SpreadCountsTheGridCellsWithInliers) {
  const Intrinsics camera = vgaCamera();
  Correspondences pairs;
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector2d pixel(10 + (i % 5) * 5, 10 + (i / 5) * 4);
    const double depth = 2.0 + 0.01 * i;
    pairs.add(pixel, Eigen::Vector3d((pixel.x() - 320) / 500 * depth, (pixel.y() - 240) / 500 * depth, depth), 3.0f);
  }
  PnpResult pose = success();
  pose.camera_to_world = Pose::identity();
  const PoseEvidence evidence = measureEvidence(pairs, camera, pose, PnpOptions{}, nullptr);
  EXPECT_DOUBLE_EQ(evidence.inlier_spread, 1.0 / 64);
  EXPECT_LT(evidence.agreement_translation, 0);  // no second estimate given

  // Without a pose nothing is measured but the count: "7 inliers of 30 (ratio 0, spread 0)" before.
  PnpResult failed;
  failed.status = PnpStatus::kTooFewInliers;
  failed.inliers = 7;
  failed.used_correspondences = 28;
  const PoseEvidence unmeasured = measureEvidence(pairs, camera, failed, PnpOptions{}, nullptr);
  EXPECT_DOUBLE_EQ(unmeasured.inlier_ratio, 0.25);
  EXPECT_LT(unmeasured.inlier_spread, 0);
  EXPECT_LT(unmeasured.predicted_centre_sigma, 0);
}

// The predicted uncertainty comes from the inliers' residuals: pixels 1 px off (per axis) give a
// residual sigma near 1 px, and the relative figure is the centre's over the median inlier depth.
TEST(Verdict, PredictedUncertaintyComesFromTheInliers) {
  const Intrinsics camera = vgaCamera();
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 640), v(0, 480);
  std::normal_distribution<double> noise(0, 1);
  Correspondences pairs;
  const double depth = 4;
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector2d pixel(u(rng), v(rng));
    pairs.add(pixel + Eigen::Vector2d(noise(rng), noise(rng)), camera.backproject(pixel, depth), 3.0f);
  }
  PnpResult pose = success();
  pose.camera_to_world = Pose::identity();
  const PoseEvidence evidence = measureEvidence(pairs, camera, pose, PnpOptions{}, nullptr);
  EXPECT_NEAR(evidence.residual_sigma_px, 1.0, 0.15);
  EXPECT_GT(evidence.predicted_centre_sigma, 0);
  EXPECT_NEAR(evidence.predicted_centre_sigma_relative, evidence.predicted_centre_sigma / depth, 1e-12);
  EXPECT_GT(evidence.predicted_rotation_sigma_deg, 0);
  EXPECT_LT(evidence.predicted_rotation_sigma_deg, 1);
}

// Pixels seen with 0.75 times the focal length given (3 px of noise, depths 1-6 m) and a pose
// estimated with the one given: the fit over the inliers alone is drawn back towards the focal
// length given; re-selecting the pairs the fit explains (the classical methods) finds the true one,
// and FastForward's mode keeps the single fit.
TEST(Verdict, IntrinsicsFitsReselectTheirPairsUnlessTold) {
  const Intrinsics given = vgaCamera();
  Intrinsics truth = given;
  truth.fx *= 0.75;
  truth.fy *= 0.75;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0, 640), v(0, 480), depth(1, 6);
  std::normal_distribution<double> noise(0, 3);
  Correspondences pairs;
  for (int i = 0; i < 300; ++i) {
    const Eigen::Vector2d pixel(u(rng), v(rng));
    pairs.add(pixel + Eigen::Vector2d(noise(rng), noise(rng)), truth.backproject(pixel, depth(rng)), 3.0f);
  }
  const PnpResult pose = estimatePose(pairs, given, PnpOptions{});
  ASSERT_TRUE(pose.ok());
  const PoseEvidence reselected = measureEvidence(pairs, given, pose, PnpOptions{}, nullptr);
  const PoseEvidence inliers_only =
      measureEvidence(pairs, given, pose, PnpOptions{}, nullptr, IntrinsicsFitPairs::kInliers);
  EXPECT_NEAR(reselected.focal_scale, 0.75, 0.01);
  EXPECT_GT(inliers_only.focal_scale, 0.78);
}

}  // namespace
}  // namespace ffloc
