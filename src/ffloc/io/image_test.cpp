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

// A PNG whose header (its CRC right, then an empty IDAT, so that libpng reaches OpenCV's size
// check) claims 100000 x 100000 pixels: OpenCV refuses it by its pixel limit with
// its own assertion text; the user is told the size instead.
TEST(ReadImage, OversizedHeaderIsReportedWithItsSize) {
  const auto dir = testing::makeTempDir("ffloc-image");
  const auto huge = dir / "huge.png";
  const unsigned char header[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 0, 0, 0, 13, 'I', 'H', 'D', 'R',
                                  0, 0x01, 0x86, 0xa0, 0, 0x01, 0x86, 0xa0, 8, 2, 0, 0, 0, 0x27, 0x30, 0x9c, 0x9f,
                                  0, 0, 0, 0, 'I', 'D', 'A', 'T', 0x35, 0xaf, 0x06, 0x1e};
  std::ofstream(huge, std::ios::binary).write(reinterpret_cast<const char*>(header), sizeof(header));
  try {
    readImageRgb(huge);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("huge.png"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("100000 x 100000 pixels"), std::string::npos) << e.what();
  }
}

// A 16-bit PNG holding 12 bits (a machine-vision camera's) came back with its top byte only: at
// most 15 of 255, and no query localized.
TEST(ReadImage, ImagesOfMoreThanEightBitsKeepTheirRange) {
  const auto dir = testing::makeTempDir("ffloc-image-depth");
  cv::Mat3b bgr(6, 8);
  cv::randu(bgr, cv::Scalar::all(0), cv::Scalar::all(256));
  bgr(0, 0) = cv::Vec3b(255, 255, 255);
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  for (const auto& [name, scale] : {std::pair<std::string, double>{"twelve.png", 16.0}, {"ten.png", 4.0}, {"full.png", 257.0}}) {
    cv::Mat wide;
    bgr.convertTo(wide, CV_16U, scale);
    ASSERT_TRUE(cv::imwrite((dir / name).string(), wide));
    const cv::Mat read = readImageRgb(dir / name);
    ASSERT_EQ(read.type(), CV_8UC3) << name;
    EXPECT_LE(cv::norm(read, rgb, cv::NORM_INF), 1) << name;  // 257 v / 256 rounds up from v = 128
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
