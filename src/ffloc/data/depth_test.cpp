#include "ffloc/data/depth.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <opencv2/imgcodecs.hpp>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/data/scene_test_util.h"

namespace ffloc {
namespace {

using testing::expectInputError;

Frame frameWithDepth(const std::filesystem::path& depth_path, int width, int height) {
  Frame frame;
  frame.name = "f.png";
  frame.intrinsics.width = width;
  frame.intrinsics.height = height;
  frame.intrinsics.fx = frame.intrinsics.fy = 10;
  DepthSource depth;
  depth.path = depth_path;
  frame.depth = depth;
  return frame;
}

TEST(Depth, ReadsUint16MillimetresAndMasksInvalid) {
  const auto dir = testing::makeTempDir("ffloc-depth");
  cv::Mat1w stored(2, 3);
  stored << 1000, 0, 65535, 2500, 1, 40000;
  ASSERT_TRUE(cv::imwrite((dir / "d.png").string(), stored));
  const cv::Mat1f depth = readDepthMetres(frameWithDepth(dir / "d.png", 3, 2));
  ASSERT_EQ(depth.size(), cv::Size(3, 2));
  EXPECT_FLOAT_EQ(depth(0, 0), 1.0f);
  EXPECT_EQ(depth(0, 1), 0.0f);
  EXPECT_EQ(depth(0, 2), 0.0f);
  EXPECT_FLOAT_EQ(depth(1, 0), 2.5f);
  EXPECT_FLOAT_EQ(depth(1, 1), 0.001f);
  EXPECT_FLOAT_EQ(depth(1, 2), 40.0f);
}

TEST(Depth, FloatTiffRoundTripsAndMasksNanAndNegative) {
  const auto dir = testing::makeTempDir("ffloc-depth");
  cv::Mat1f written(2, 2);
  written << 1.25f, std::numeric_limits<float>::quiet_NaN(), -3.0f, 7.5f;
  writeDepth(written, dir / "d.tiff");
  Frame frame = frameWithDepth(dir / "d.tiff", 2, 2);
  frame.depth->scale = 1.0;
  const cv::Mat1f depth = readDepthMetres(frame);
  EXPECT_EQ(depth(0, 0), 1.25f);
  EXPECT_EQ(depth(0, 1), 0.0f);
  EXPECT_EQ(depth(1, 0), 0.0f);
  EXPECT_EQ(depth(1, 1), 7.5f);
  expectInputError([&] { writeDepth(written, dir / "d.png"); }, {"d.png", "tif"});
  // A depth beyond any scene is no measurement: 1e300 metres overflowed the float it is kept in.
  frame.depth->scale = 1e300;
  EXPECT_EQ(cv::countNonZero(readDepthMetres(frame)), 0);
  frame.depth->scale = 1e8;  // 7.5e8 m is still inside kMaxCameraDistance, 1.25e8 too
  EXPECT_EQ(cv::countNonZero(readDepthMetres(frame)), 2);
}

TEST(Depth, BadFilesNameTheFile) {
  const auto dir = testing::makeTempDir("ffloc-depth");
  expectInputError([&] { readDepthMetres(frameWithDepth(dir / "missing.png", 3, 2)); },
                   {"missing.png", "not found"});
  testing::writeTextFile(dir / "garbage.png", "not an image");
  expectInputError([&] { readDepthMetres(frameWithDepth(dir / "garbage.png", 3, 2)); },
                   {"garbage.png", "cannot decode"});
  ASSERT_TRUE(cv::imwrite((dir / "small.png").string(), cv::Mat1w(2, 3, uint16_t(5))));
  expectInputError([&] { readDepthMetres(frameWithDepth(dir / "small.png", 640, 480)); },
                   {"small.png", "3x2", "640x480"});
  ASSERT_TRUE(cv::imwrite((dir / "rgb.png").string(), cv::Mat3b(2, 3, cv::Vec3b(1, 2, 3))));
  expectInputError([&] { readDepthMetres(frameWithDepth(dir / "rgb.png", 3, 2)); }, {"rgb.png"});
  // Read as grey, a 16-bit colour PNG was a weighted sum of its channels, taken as millimetres.
  ASSERT_TRUE(cv::imwrite((dir / "rgb16.png").string(), cv::Mat_<cv::Vec3w>(2, 3, cv::Vec3w(1000, 2000, 3000))));
  expectInputError([&] { readDepthMetres(frameWithDepth(dir / "rgb16.png", 3, 2)); },
                   {"rgb16.png", "colour or alpha channels (decoded to 3 channels; grey with alpha decodes to 3 too); expected one grey channel"});
  Frame no_depth = frameWithDepth(dir / "x.png", 3, 2);
  no_depth.depth.reset();
  expectInputError([&] { readDepthMetres(no_depth); }, {"f.png", "no depth"});
}

}  // namespace
}  // namespace ffloc
