#include "ffloc/io/image.h"

#include <gtest/gtest.h>

#include <fstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"

namespace ffloc {
namespace {

TEST(ReadImage, ErrorsNameTheFile) {
  const auto dir = testing::makeTempDir("ffloc-image");
  try {
    readImageRgb(dir / "missing.png");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.png"), std::string::npos);
  }
  const auto garbage = dir / "garbage.jpg";
  std::ofstream(garbage) << "not a jpeg";
  try {
    readImageRgb(garbage);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("garbage.jpg"), std::string::npos);
  }
}

TEST(ReadImage, ReadsRealImageAsRgb) {
  FFLOC_REQUIRE_SHARED(path, "data/7scenes_redkitchen/frame-000000.color.jpg");
  const cv::Mat rgb = readImageRgb(path);
  EXPECT_EQ(rgb.cols, 640);
  EXPECT_EQ(rgb.rows, 480);
  EXPECT_EQ(rgb.type(), CV_8UC3);
  const cv::Mat bgr = cv::imread(path.string());
  EXPECT_EQ(rgb.at<cv::Vec3b>(100, 100)[0], bgr.at<cv::Vec3b>(100, 100)[2]);
}

}  // namespace
}  // namespace ffloc
