#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/data/dataset.h"
#include "ffloc/eval/evaluator.h"
#include "ffloc/eval/sift_baseline_source.h"

namespace ffloc {
namespace {

// Small enough for a quick test, large enough for the Strecha facades.
SiftBaselineOptions fastOptions() {
  SiftBaselineOptions options;
  options.sift.max_image_size = 1024;
  options.sift.max_features = 4000;
  return options;
}

// One preparation serves both checks: extracting the fountain's features is the slow part.
TEST(SiftBaseline, LocalisesStrechaFountainQueriesWithCorrectPairs) {
  FFLOC_REQUIRE_SHARED(dir, "data/strecha_fountain_p11");
  const Scene scene = loadDataset(dir);
  SiftBaselineSource source(fastOptions());
  EvaluationOptions evaluation;
  evaluation.quiet = true;
  const std::vector<FrameResult> results = evaluate(scene, source, evaluation);
  ASSERT_EQ(results.size(), 3u);
  for (const FrameResult& r : results) {
    EXPECT_TRUE(r.succeeded()) << r.frame;
    EXPECT_GT(r.correspondences, 300) << r.frame;
    EXPECT_LT(r.translation_error, 0.05) << r.frame;
    EXPECT_LT(r.rotation_error_deg, 0.5) << r.frame;
  }

  // Against the ground-truth query pose, most pairs must be right to within a few pixels at the
  // working resolution (1024 / 3072 of the original, so 3 working px = 9 original px).
  const size_t query = scene.queryIndices().front();
  const Frame& frame = scene.frames[query];
  const Correspondences pairs = source.correspondences(scene, query);
  ASSERT_GT(pairs.size(), 300u);
  const Intrinsics camera = frame.intrinsics.undistorted();
  size_t close = 0;
  for (size_t i = 0; i < pairs.size(); ++i) {
    EXPECT_GE(pairs.confidences[i], 3.0f);
    const Eigen::Vector3d p = frame.camera_to_world.R.transpose() * (pairs.points[i] - frame.camera_to_world.t);
    if (p.z() > 0 && (camera.project(p) - pairs.pixels[i]).norm() < 9.0) ++close;
  }
  EXPECT_GT(static_cast<double>(close) / pairs.size(), 0.8);
}

TEST(SiftBaseline, RetrievalRanksEveryMappingFrameAndMatchesOnlyTopK) {
  FFLOC_REQUIRE_SHARED(dir, "data/strecha_fountain_p11");
  const Scene scene = loadDataset(dir);
  SiftBaselineOptions options = fastOptions();
  options.sift.max_image_size = 640;
  options.sift.max_features = 1500;
  options.retrieval_top_k = 3;
  SiftBaselineSource source(options);
  source.prepare(scene);
  const std::vector<size_t> mapping = scene.mappingIndices();
  for (size_t query : scene.queryIndices()) {
    std::vector<size_t> ranked = source.rankMappingFrames(scene, query);
    ASSERT_EQ(ranked.size(), mapping.size());
    // The queries sit between two mapping views along the path; the nearest camera centre must
    // be among the 3 retrieved.
    const auto nearest = *std::min_element(mapping.begin(), mapping.end(), [&](size_t a, size_t b) {
      return translationError(scene.frames[a].camera_to_world, scene.frames[query].camera_to_world) <
             translationError(scene.frames[b].camera_to_world, scene.frames[query].camera_to_world);
    });
    EXPECT_NE(std::find(ranked.begin(), ranked.begin() + 3, nearest), ranked.begin() + 3)
        << scene.frames[query].name;
    std::sort(ranked.begin(), ranked.end());
    EXPECT_EQ(ranked, mapping);
  }
}

TEST(SiftBaseline, ImageSizeThatDisagreesWithIntrinsicsIsAnInputError) {
  FFLOC_REQUIRE_SHARED(dir, "data/strecha_fountain_p11");
  Scene scene = loadDataset(dir);
  Frame& frame = scene.frames[scene.mappingIndices().front()];
  frame.intrinsics = frame.intrinsics.scaled(0.5, 0.5, frame.intrinsics.width / 2, frame.intrinsics.height / 2);
  SiftBaselineSource source(fastOptions());
  try {
    source.prepare(scene);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(frame.image_path.filename().string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("intrinsics"), std::string::npos) << e.what();
  }
}

TEST(SiftBaseline, UnreadableMappingImageIsAnInputError) {
  FFLOC_REQUIRE_SHARED(dir, "data/strecha_fountain_p11");
  Scene scene = loadDataset(dir);
  const std::filesystem::path tmp = testing::makeTempDir("sift_baseline");
  const std::filesystem::path broken = tmp / "broken.jpg";
  std::ofstream(broken) << "not a jpeg";
  scene.frames[scene.mappingIndices().front()].image_path = broken;
  SiftBaselineSource source(fastOptions());
  EXPECT_THROW(source.prepare(scene), InputError);
  std::filesystem::remove_all(tmp);
}

}  // namespace
}  // namespace ffloc
