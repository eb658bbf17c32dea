#include "ffloc/data/overlap.h"

#include <gtest/gtest.h>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/data/dataset.h"
#include "ffloc/data/depth.h"

namespace ffloc {
namespace {

// 100 x 80 pixels, f = 100, principal point at the image centre (49.5, 39.5).
Frame makeFrame(const Eigen::Vector3d& centre) {
  Frame f;
  f.name = "hand-made";
  f.intrinsics.width = 100;
  f.intrinsics.height = 80;
  f.intrinsics.fx = f.intrinsics.fy = 100;
  f.intrinsics.cx = 49.5;
  f.intrinsics.cy = 39.5;
  f.camera_to_world.t = centre;
  return f;
}

// The depth a camera at `centre`, looking down +z, sees of the plane z = plane_z.
cv::Mat1f planeDepth(const Frame& f, double plane_z) {
  return cv::Mat1f(f.intrinsics.height, f.intrinsics.width,
                   static_cast<float>(plane_z - f.camera_to_world.t.z()));
}

TEST(ViewOverlap, ViewWithItselfIsOne) {
  const Frame a = makeFrame({0, 0, 0});
  const cv::Mat1f depth = planeDepth(a, 2.0);
  EXPECT_DOUBLE_EQ(viewOverlap(a, depth, a, depth), 1.0);
}

TEST(ViewOverlap, SidewaysMotionIsExactAndSymmetric) {
  // A 0.4 m baseline at 2 m depth with f = 100 shifts every pixel by exactly 20 columns, so
  // 80 of the 100 columns stay in view, both ways.
  const Frame a = makeFrame({0, 0, 0});
  const Frame b = makeFrame({0.4, 0, 0});
  const cv::Mat1f da = planeDepth(a, 2.0), db = planeDepth(b, 2.0);
  EXPECT_DOUBLE_EQ(viewOverlap(a, da, b, db), 0.8);
  EXPECT_DOUBLE_EQ(viewOverlap(b, db, a, da), 0.8);
  EXPECT_DOUBLE_EQ(pairOverlap(a, da, b, db), 0.8);
}

TEST(ViewOverlap, ZoomIsAsymmetricInTheExpectedWay) {
  // B at half A's distance to the plane sees the central half of A's view in each direction:
  // A's columns 25..74 and rows 20..59 land in B (a quarter of A), all of B lands in A.
  const Frame a = makeFrame({0, 0, 0});
  const Frame b = makeFrame({0, 0, 1.0});
  const cv::Mat1f da = planeDepth(a, 2.0), db = planeDepth(b, 2.0);
  EXPECT_DOUBLE_EQ(viewOverlap(a, da, b, db), 0.25);
  EXPECT_DOUBLE_EQ(viewOverlap(b, db, a, da), 1.0);
  EXPECT_DOUBLE_EQ(pairOverlap(a, da, b, db), 0.25);
}

TEST(ViewOverlap, OccludedAndInvalidPixelsDoNotCount) {
  const Frame a = makeFrame({0, 0, 0});
  const Frame b = makeFrame({0.4, 0, 0});
  cv::Mat1f da = planeDepth(a, 2.0), db = planeDepth(b, 2.0);
  // An occluder at 1 m covering B's left 30 columns: A's columns 20..49 land there and fail
  // the depth check. A's top 8 rows have no depth and are not counted at all.
  db(cv::Rect(0, 0, 30, 80)).setTo(1.0f);
  da(cv::Rect(0, 0, 100, 8)).setTo(0.0f);
  // Visible in B: A's columns 20..99 (80), minus 30 occluded, over all 100 valid columns.
  EXPECT_DOUBLE_EQ(viewOverlap(a, da, b, db), 0.5);
  // Within the tolerance the occluder is not one: 5% of 2 m is 0.1 m.
  db(cv::Rect(0, 0, 30, 80)).setTo(1.95f);
  EXPECT_DOUBLE_EQ(viewOverlap(a, da, b, db), 0.8);
}

TEST(ViewOverlap, SmallerDepthMapsRescaleTheIntrinsics) {
  const Frame a = makeFrame({0, 0, 0});
  const Frame b = makeFrame({0.4, 0, 0});
  const cv::Mat1f da(40, 50, 2.0f), db(40, 50, 2.0f);
  // At half resolution the shift is 10 of 50 columns.
  EXPECT_DOUBLE_EQ(viewOverlap(a, da, b, db), 0.8);
}

TEST(ViewOverlap, FacingAwayOrNoDepthIsZero) {
  const Frame a = makeFrame({0, 0, 0});
  Frame b = makeFrame({0, 0, 0});
  b.camera_to_world.R = Eigen::Vector3d(1, -1, -1).asDiagonal();  // looking down -z
  const cv::Mat1f depth = planeDepth(a, 2.0);
  EXPECT_EQ(viewOverlap(a, depth, b, depth), 0.0);
  EXPECT_EQ(viewOverlap(a, cv::Mat1f(80, 100, 0.0f), a, depth), 0.0);
}

TEST(ViewOverlap, RejectsDistortionAndBadStride) {
  Frame a = makeFrame({0, 0, 0});
  const cv::Mat1f depth = planeDepth(a, 2.0);
  OverlapOptions options;
  options.stride = 0;
  EXPECT_THROW(viewOverlap(a, depth, a, depth, options), InputError);
  a.intrinsics.distortion = {0.1, 0, 0, 0};
  EXPECT_THROW(viewOverlap(a, depth, a, depth), InputError);
}

TEST(ViewOverlap, SevenScenesNeighboursOverlapMoreThanDistantFrames) {
  FFLOC_REQUIRE_SHARED(dir, "data/7scenes_redkitchen");
  const Scene scene = loadDataset(dir);
  ASSERT_GE(scene.frames.size(), 200u);
  OverlapOptions options;
  options.stride = 4;
  auto overlap = [&](size_t i, size_t j) {
    return pairOverlap(scene.frames[i], readDepthMetres(scene.frames[i]), scene.frames[j],
                       readDepthMetres(scene.frames[j]), options);
  };
  // Frames 4 apart in the original 30 Hz sequence (adjacent here) see nearly the same thing.
  const double neighbours = overlap(0, 1);
  const double far = overlap(0, 150);
  EXPECT_GT(neighbours, 0.8);
  EXPECT_LT(far, neighbours - 0.3);
  // A frame with itself: everything agrees.
  EXPECT_DOUBLE_EQ(overlap(10, 10), 1.0);
}

}  // namespace
}  // namespace ffloc
