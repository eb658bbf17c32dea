#include "ffloc/localization/localizer.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <optional>
#include <random>
#include <thread>
#include <utility>
#include <vector>

#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"

namespace ffloc {
namespace {

Intrinsics camera() { return Intrinsics{500, 500, 320, 240, 640, 480, {}}; }  // fx, fy, cx, cy, width, height

Pose truePose() {
  Pose pose;
  pose.R = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1, 0.1).normalized()).toRotationMatrix();
  pose.t = Eigen::Vector3d(0.5, -0.2, 1.0);
  return pose;
}

// `count` pairs seen by the camera at truePose(), spread over the image, 0.5 px of noise.
Correspondences exactPairs(size_t count, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 640), v(0, 480), depth(2, 6);
  std::normal_distribution<double> noise(0, 0.5);
  const Intrinsics k = camera();
  const Pose pose = truePose();
  Correspondences pairs;
  for (size_t i = 0; i < count; ++i) {
    const Eigen::Vector2d pixel(u(rng), v(rng));
    const Eigen::Vector3d world = pose * k.backproject(pixel, depth(rng));
    pairs.add(pixel + Eigen::Vector2d(noise(rng), noise(rng)), world, 2.0f);
  }
  return pairs;
}

// Pairs of nothing: random pixels and random points.
Correspondences randomPairs(size_t count, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 640), v(0, 480), x(-5, 5);
  Correspondences pairs;
  for (size_t i = 0; i < count; ++i) pairs.add({u(rng), v(rng)}, {x(rng), x(rng), x(rng)}, 2.0f);
  return pairs;
}

// A method whose first pairs and looks are given: image 0 first, image 1 on the look at more
// images, then the nearby pairs (none: no such look).
class ScriptedLocalizer : public Localizer {
 public:
  ScriptedLocalizer(Correspondences first, Correspondences second_look, std::optional<Correspondences> nearby = {})
      : first_(std::move(first)), second_look_(std::move(second_look)), nearby_(std::move(nearby)) {}
  LocalizationMethod method() const override { return LocalizationMethod::kClassical; }
  bool metric() const override { return true; }
  const std::vector<MapCamera>& cameras() const override { return cameras_; }
  int looks() const { return looks_; }
  int nearbyLooks() const { return nearby_looks_; }

 protected:
  void predict(const cv::Mat&, const Intrinsics& intrinsics, const std::string&, const LocalizeOptions&,
               LocalizationResult& result, std::optional<PnpResult>&, PoseGuidedLooks& pose_guided) const override {
    result.camera = intrinsics;
    result.correspondences = first_;
    result.selected = {0};
    pose_guided.more_images = [this](const Pose&, LocalizationResult& again) {
      ++looks_;
      append(second_look_, again.correspondences);
      again.selected.push_back(1);
      std::this_thread::sleep_for(std::chrono::milliseconds(20));  // a look that takes its time
    };
    if (nearby_)
      pose_guided.nearby_pairs = [this](const Pose&, LocalizationResult& again) {
        ++nearby_looks_;
        append(*nearby_, again.correspondences);
      };
  }

 private:
  static void append(const Correspondences& pairs, Correspondences& to) {
    for (size_t i = 0; i < pairs.size(); ++i) to.add(pairs.pixels[i], pairs.points[i], pairs.confidences[i]);
  }

  std::vector<MapCamera> cameras_;
  Correspondences first_, second_look_;
  std::optional<Correspondences> nearby_;
  mutable std::atomic<int> looks_{0}, nearby_looks_{0};
};

LocalizationResult localizeWith(const ScriptedLocalizer& localizer, const LocalizeOptions& options = {}) {
  return localizer.localize(cv::Mat(480, 640, CV_8UC3, cv::Scalar::all(0)), camera(), "q", options);
}

// 14 right pairs give a pose, but too few for its half-sample twin: `uncertain`, so a second look.
TEST(PoseGuidedMatching, ASecondLookWithPairsGivesTheNewAnswer) {
  const ScriptedLocalizer localizer(exactPairs(14, 1), exactPairs(300, 2));
  const LocalizationResult result = localizeWith(localizer);
  EXPECT_EQ(localizer.looks(), 1);
  EXPECT_TRUE(result.localized()) << result.verdict.reason;
  EXPECT_EQ(result.selected, (std::vector<size_t>{0, 1}));
  EXPECT_EQ(result.correspondences.size(), 314u);
  EXPECT_LT(translationError(result.pnp.camera_to_world, truePose()), 0.05);
}

TEST(PoseGuidedMatching, ALookThatAddsNothingOrNoPoseKeepsTheFirstAnswerAndItsTime) {
  const ScriptedLocalizer alone(exactPairs(14, 1), Correspondences{});
  LocalizeOptions no_look;
  no_look.pose_guided_retrieval = false;
  const LocalizationResult first = localizeWith(alone, no_look);
  EXPECT_EQ(alone.looks(), 0);
  ASSERT_TRUE(first.pnp.ok());
  ASSERT_EQ(first.verdict.status, PoseStatus::kUncertain);

  for (const Correspondences& look : {Correspondences{}, randomPairs(3000, 3)}) {
    const ScriptedLocalizer localizer(exactPairs(14, 1), look);
    const LocalizationResult result = localizeWith(localizer);
    EXPECT_EQ(localizer.looks(), 1);
    EXPECT_EQ(result.verdict.status, PoseStatus::kUncertain);
    EXPECT_EQ(result.selected, first.selected);
    EXPECT_EQ(result.correspondences.size(), first.correspondences.size());
    EXPECT_EQ(result.pnp.inliers, first.pnp.inliers);
    EXPECT_TRUE(result.pnp.camera_to_world.matrix().isApprox(first.pnp.camera_to_world.matrix()));
    EXPECT_GE(result.timings.matching, 0.02);  // the look's time is still counted
  }
}

TEST(PoseGuidedMatching, ALocalizedPoseTakesNoSecondLook) {
  const ScriptedLocalizer localizer(exactPairs(300, 4), exactPairs(300, 5));
  const LocalizationResult result = localizeWith(localizer);
  EXPECT_TRUE(result.localized()) << result.verdict.reason;
  EXPECT_EQ(localizer.looks(), 0);
  EXPECT_EQ(result.selected, (std::vector<size_t>{0}));
}

// The nearby pairs come last, after a look at more images that left the pose `uncertain`, and
// their answer is taken only when `localized`: pairs a pose chose agree with it by construction.
TEST(PoseGuidedMatching, NearbyPairsAreTakenOnlyWhenTheyGiveALocalizedPose) {
  const ScriptedLocalizer without(exactPairs(14, 1), Correspondences{});
  const LocalizationResult before = localizeWith(without);
  ASSERT_EQ(before.verdict.status, PoseStatus::kUncertain);

  const ScriptedLocalizer useless(exactPairs(14, 1), Correspondences{}, randomPairs(3000, 3));
  const LocalizationResult kept = localizeWith(useless);
  EXPECT_EQ(useless.looks(), 1);
  EXPECT_EQ(useless.nearbyLooks(), 1);
  EXPECT_EQ(kept.verdict.status, PoseStatus::kUncertain);
  EXPECT_EQ(kept.correspondences.size(), before.correspondences.size());
  EXPECT_TRUE(kept.pnp.camera_to_world.matrix().isApprox(before.pnp.camera_to_world.matrix()));

  const ScriptedLocalizer useful(exactPairs(14, 1), Correspondences{}, exactPairs(300, 2));
  const LocalizationResult taken = localizeWith(useful);
  EXPECT_TRUE(taken.localized()) << taken.verdict.reason;
  EXPECT_EQ(taken.correspondences.size(), 314u);
  EXPECT_LT(translationError(taken.pnp.camera_to_world, truePose()), 0.05);

  const ScriptedLocalizer localized_first(exactPairs(14, 1), exactPairs(300, 2), exactPairs(300, 5));
  EXPECT_TRUE(localizeWith(localized_first).localized());
  EXPECT_EQ(localized_first.nearbyLooks(), 0);  // the look at more images was enough

  LocalizeOptions no_look;
  no_look.pose_guided_retrieval = false;
  localizeWith(useful, no_look);
  EXPECT_EQ(useful.nearbyLooks(), 1);  // still the one of the query above
}

TEST(PoseGuidedMatching, AStopRequestedDuringTheLookStopsBeforeTheSecondPnp) {
  const ScriptedLocalizer localizer(exactPairs(14, 1), exactPairs(300, 2));
  LocalizeOptions options;
  options.stop_requested = [&localizer] { return localizer.looks() > 0; };
  try {
    localizeWith(localizer, options);
    FAIL() << "the query ran to its end";
  } catch (const QueryStopped& stopped) {
    EXPECT_STREQ(stopped.what(), "stopped before PnP on the pose-guided look");
  }
}

// Records what each query gave it: the image's size and the intrinsics.
class RecordingLocalizer : public Localizer {
 public:
  explicit RecordingLocalizer(std::vector<MapCamera> cameras) : cameras_(std::move(cameras)) {}
  LocalizationMethod method() const override { return LocalizationMethod::kClassical; }
  bool metric() const override { return true; }
  const std::vector<MapCamera>& cameras() const override { return cameras_; }
  mutable std::vector<std::pair<cv::Size, Intrinsics>> queries;

 protected:
  void predict(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string&, const LocalizeOptions&,
               LocalizationResult& result, std::optional<PnpResult>&, PoseGuidedLooks&) const override {
    queries.emplace_back(rgb.size(), intrinsics);
    result.camera = intrinsics;
  }

 private:
  std::vector<MapCamera> cameras_;
};

TEST(WarmUp, LocalizesAMadeUpImageOfTheFirstMappingCamerasSizeAndIntrinsics) {
  MapCamera first{"a", Pose{}, Intrinsics{300, 310, 200, 150, 400, 300, {}}};
  MapCamera second{"b", Pose{}, Intrinsics{500, 500, 320, 240, 640, 480, {}}};
  const RecordingLocalizer localizer({first, second});
  EXPECT_EQ(warmUp(localizer, LocalizeOptions{}).rfind("warmed up by a made-up query in ", 0), 0u);
  ASSERT_EQ(localizer.queries.size(), 1u);
  EXPECT_EQ(localizer.queries[0].first, cv::Size(400, 300));
  EXPECT_EQ(localizer.queries[0].second.fx, 300);
  EXPECT_EQ(localizer.queries[0].second.cy, 150);
}

// An outside probe edited a map's first focal length to 1e6 px: `ffloc serve` ended at start
// with a message about fx, where `ffloc localize` answered queries that gave their own.
TEST(WarmUp, AFirstCameraNoQueryCouldHaveIsSaidAndNotLocalized) {
  MapCamera absurd{"a", Pose{}, Intrinsics{1e6, 1e6, 200, 150, 400, 300, {}}};
  const RecordingLocalizer localizer({absurd});
  const std::string said = warmUp(localizer, LocalizeOptions{});
  EXPECT_EQ(said.rfind("not warmed up: a made-up query at its first mapping camera was refused: ", 0), 0u) << said;
  EXPECT_NE(said.find("fx"), std::string::npos) << said;
  EXPECT_TRUE(localizer.queries.empty());
}

TEST(WarmUp, AMapWithoutCamerasIsWarmedAtAVgaCamera) {
  const RecordingLocalizer localizer({});
  warmUp(localizer, LocalizeOptions{});
  ASSERT_EQ(localizer.queries.size(), 1u);
  EXPECT_EQ(localizer.queries[0].first, cv::Size(640, 480));
  EXPECT_NO_THROW(checkIntrinsicsFitImage(localizer.queries[0].second, 640, 480));
}

}  // namespace
}  // namespace ffloc
