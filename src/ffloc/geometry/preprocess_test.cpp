#include "ffloc/geometry/preprocess.h"

#include <gtest/gtest.h>

#include <fstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"

namespace ffloc {
namespace {

TEST(PreprocessGeometry, MatchesDust3rSizes) {
  // 640x480 -> 512x384, already multiples of 16.
  auto g = preprocessGeometry(640, 480);
  EXPECT_EQ(g.width, 512);
  EXPECT_EQ(g.height, 384);
  EXPECT_EQ(g.crop_x, 0);
  EXPECT_EQ(g.crop_y, 0);
  // 3072x2048 -> 512x341 -> crop to 512x336 about the centre (170 -> 168 half-height).
  g = preprocessGeometry(3072, 2048);
  EXPECT_EQ(g.resized_height, 341);
  EXPECT_EQ(g.width, 512);
  EXPECT_EQ(g.height, 336);
  EXPECT_EQ(g.crop_y, 170 - 168);
  // Portrait stays portrait: 1080x1920 -> 288x512.
  g = preprocessGeometry(1080, 1920);
  EXPECT_EQ(g.width, 288);
  EXPECT_EQ(g.height, 512);
  // A square becomes 4:3 unless square_ok.
  g = preprocessGeometry(600, 600);
  EXPECT_EQ(g.width, 512);
  EXPECT_EQ(g.height, 384);
  PreprocessOptions square;
  square.square_ok = true;
  g = preprocessGeometry(600, 600, square);
  EXPECT_EQ(g.height, 512);
  // A configured long side.
  PreprocessOptions small;
  small.long_side = 224;
  g = preprocessGeometry(640, 480, small);
  EXPECT_EQ(g.width, 224);
  EXPECT_EQ(g.height, 160);
}

TEST(PreprocessGeometry, PixelMappingRoundTrips) {
  const auto g = preprocessGeometry(3072, 2048);
  const Eigen::Vector2d p(1234.25, 876.5);
  EXPECT_LT((g.toOriginal(g.toPreprocessed(p)) - p).norm(), 1e-9);
}

TEST(PreprocessGeometry, RejectsTinyImages) {
  EXPECT_THROW(preprocessGeometry(0, 10), InputError);
  PreprocessOptions options;
  options.long_side = 8;
  EXPECT_THROW(preprocessGeometry(640, 480, options), InputError);
}

// A 3D point must land on the same image content before and after preprocessing, under the
// updated intrinsics: render a bright dot where the point projects, preprocess, and find the dot.
TEST(PreprocessImage, PointProjectsToSameContent) {
  Intrinsics camera;
  camera.width = 3072;
  camera.height = 2048;
  camera.fx = 2759.48;
  camera.fy = 2764.16;
  camera.cx = 1520.69;
  camera.cy = 1006.81;
  const Eigen::Vector3d point(0.7, -0.4, 3.0);
  const Eigen::Vector2d original = camera.project(point);

  cv::Mat image(camera.height, camera.width, CV_8UC3, cv::Scalar(0, 0, 0));
  cv::circle(image, cv::Point2d(original.x(), original.y()) * 16.0, 40 * 16, cv::Scalar(255, 255, 255),
             cv::FILLED, cv::LINE_AA, 4);
  const PreprocessedImage pre = preprocessImage(image, camera);
  const Eigen::Vector2d expected = pre.intrinsics.project(point);

  cv::Mat gray;
  cv::cvtColor(pre.rgb, gray, cv::COLOR_RGB2GRAY);
  const cv::Moments m = cv::moments(gray, false);
  const Eigen::Vector2d centroid(m.m10 / m.m00, m.m01 / m.m00);
  EXPECT_LT((centroid - expected).norm(), 0.05) << "centroid " << centroid.transpose() << " expected "
                                                << expected.transpose();
  EXPECT_EQ(pre.rgb.cols, pre.intrinsics.width);
  EXPECT_EQ(pre.rgb.rows, pre.intrinsics.height);
}

}  // namespace
}  // namespace ffloc
