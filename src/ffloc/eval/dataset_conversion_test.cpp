// Every dataset writer against its reader: a tiny synthetic RGB-D scene is written in each
// format, read back through format detection, and must keep its frames, splits, intrinsics and
// poses, and localise perfectly with its own depth (oracle-depth through the whole harness).
#include <gtest/gtest.h>

#include <map>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/data/dataset.h"
#include "ffloc/data/dataset_writers.h"
#include "ffloc/synthetic/synthetic.h"
#include "ffloc/eval/evaluator.h"
#include "ffloc/eval/metrics.h"
#include "ffloc/eval/oracle_depth_source.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

// One scene for every format: 96x72 pixels, 5 mapping and 3 query frames, frame 1 unassigned.
const Scene& sourceScene() {
  static const Scene scene = [] {
    SyntheticOptions options;
    options.seed = 19;
    options.width = 96;
    options.height = 72;
    options.mapping_frames = 5;
    options.query_frames = 3;
    Scene generated = generateSyntheticScene(options, testing::makeTempDir("ffloc-conversion-source"));
    generated.frames[1].split = Split::kUnassigned;
    return generated;
  }();
  return scene;
}

struct FormatCase {
  std::string format;
  bool keeps_unassigned;  // else unassigned frames are written with the mapping frames
  bool has_depth;
  // map-free's world is its first mapping image: poses come back relative to it.
  bool world_is_the_first_mapping_frame = false;
};

class DatasetConversion : public ::testing::TestWithParam<FormatCase> {};

TEST_P(DatasetConversion, WriteThenReadKeepsFramesSplitsIntrinsicsPosesAndLocalisesWithOracleDepth) {
  const FormatCase& c = GetParam();
  const Scene& source = sourceScene();
  const fs::path out = testing::makeTempDir("ffloc-conversion-" + c.format) / "scene";
  const std::vector<std::string> names = writeDataset(source, c.format, out);
  ASSERT_EQ(names.size(), source.frames.size());

  ASSERT_EQ(detectDatasetFormat(out), c.format);
  Scene read = loadDataset(out);
  ASSERT_EQ(read.frames.size(), source.frames.size());
  std::map<std::string, size_t> index_of;
  for (size_t i = 0; i < read.frames.size(); ++i) index_of[read.frames[i].name] = i;
  Pose to_world = Pose::identity();
  if (c.world_is_the_first_mapping_frame) {
    for (const Frame& frame : source.frames)
      if (frame.split != Split::kQuery) {
        to_world = frame.camera_to_world.inverse();
        break;
      }
  }

  for (size_t i = 0; i < source.frames.size(); ++i) {
    const Frame& original = source.frames[i];
    SCOPED_TRACE(original.name + " -> " + names[i]);
    ASSERT_TRUE(index_of.count(names[i]));
    Frame& back = read.frames[index_of[names[i]]];
    const Split expected_split =
        original.split == Split::kUnassigned && !c.keeps_unassigned ? Split::kMapping : original.split;
    EXPECT_EQ(back.split, expected_split);
    EXPECT_EQ(back.intrinsics.width, original.intrinsics.width);
    EXPECT_EQ(back.intrinsics.height, original.intrinsics.height);
    EXPECT_NEAR(back.intrinsics.fx, original.intrinsics.fx, 1e-9);
    EXPECT_NEAR(back.intrinsics.fy, original.intrinsics.fy, 1e-9);
    EXPECT_NEAR(back.intrinsics.cx, original.intrinsics.cx, 1e-9);
    EXPECT_NEAR(back.intrinsics.cy, original.intrinsics.cy, 1e-9);
    EXPECT_EQ(back.intrinsics.distortion, original.intrinsics.distortion);
    EXPECT_LT((back.camera_to_world.matrix() - (to_world * original.camera_to_world).matrix()).cwiseAbs().maxCoeff(),
              1e-9);
    if (c.world_is_the_first_mapping_frame && names[i] == "seq0/frame_00000" + fs::path(names[i]).extension().string())
      EXPECT_LT((back.camera_to_world.matrix() - Pose::identity().matrix()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_TRUE(fs::is_regular_file(back.image_path));
    EXPECT_EQ(back.depth.has_value(), c.has_depth);
    // A format without depth is scored with the source's depth maps, which share its pixel grid.
    if (!c.has_depth) back.depth = original.depth;
  }

  // The read-back geometry, through the evaluation harness: any error in a pose or in the
  // intrinsics (a half-pixel shift included, at 96 px wide) would move the estimates.
  OracleDepthSource oracle;
  EvaluationOptions options;
  options.quiet = true;
  const MethodSummary summary = summarize(evaluate(read, oracle, options));
  EXPECT_EQ(summary.frames, 3);
  EXPECT_EQ(summary.failed, 0);
  EXPECT_DOUBLE_EQ(summary.accuracy_percent[0], 100.0);  // (5 cm, 5 deg)
  EXPECT_LT(summary.median_translation, 2e-3);
}

INSTANTIATE_TEST_SUITE_P(Formats, DatasetConversion,
                         ::testing::Values(FormatCase{"manifest", true, true}, FormatCase{"mapfree", false, true, true},
                                           FormatCase{"ace", false, true}, FormatCase{"rio10", true, true},
                                           FormatCase{"indoor6", true, false}, FormatCase{"kapture", false, true}),
                         [](const auto& info) { return info.param.format; });

TEST(DatasetConversion, UnknownFormatAndNonEmptyOutputAreInputErrors) {
  const fs::path out = testing::makeTempDir("ffloc-conversion-errors");
  EXPECT_THROW(writeDataset(sourceScene(), "blender", out / "a"), InputError);
  writeDataset(sourceScene(), "manifest", out / "b");
  EXPECT_THROW(writeDataset(sourceScene(), "ace", out / "b"), InputError);
}

}  // namespace
}  // namespace ffloc
