// Bad input of every kind is an InputError naming the file and the line or field. Each test
// writes a small dataset into a temporary folder and breaks one thing.
#include <gtest/gtest.h>
#include <limits>
#include <sys/stat.h>

#include <opencv2/imgcodecs.hpp>

#include "ffloc/core/testing/shared_data.h"
#include "ffloc/data/dataset.h"
#include "ffloc/data/depth.h"
#include "ffloc/data/scene_test_util.h"
#include "ffloc/geometry/camera.h"
#include "ffloc/io/testing/exif_jpeg.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;
using testing::expectInputError;
using testing::writeTextFile;

const char* kIdentityPose = "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";

void writeImage(const fs::path& path, int width, int height) {
  fs::create_directories(path.parent_path());
  ASSERT_TRUE(cv::imwrite(path.string(), cv::Mat3b(height, width, cv::Vec3b(40, 80, 120))));
}

// Two 8x6 frames in the flat 7-Scenes layout.
fs::path makeSevenScenes() {
  const auto dir = testing::makeTempDir("ffloc-bad-7scenes");
  writeTextFile(dir / "camera-intrinsics.txt", "5 0 3.5\n0 5 2.5\n0 0 1\n");
  for (const std::string stem : {"frame-000000", "frame-000001"}) {
    writeImage(dir / (stem + ".color.png"), 8, 6);
    EXPECT_TRUE(cv::imwrite((dir / (stem + ".depth.png")).string(), cv::Mat1w(6, 8, uint16_t(1500))));
    writeTextFile(dir / (stem + ".pose.txt"), kIdentityPose);
  }
  return dir;
}

TEST(BadInput, TinySevenScenesReads) {
  const auto dir = makeSevenScenes();
  const Scene scene = loadDataset(dir);
  ASSERT_EQ(scene.frames.size(), 2u);
  EXPECT_EQ(scene.frames[1].intrinsics.width, 8);
  EXPECT_EQ(readDepthMetres(scene.frames[1])(2, 3), 1.5f);
}

// Found by an outside probe: colour JPEGs turned by 180 degrees by their EXIF orientation, their
// depth maps not, kept their size, and the map paired each pixel with another's depth: queries came
// back `localized` 179 deg off.
TEST(BadInput, AnImageTurnedByItsExifOrientationBesideADepthMapNotTurnedIsRefused) {
  const auto dir = makeSevenScenes();
  cv::Mat3b gradient(6, 8);
  for (int y = 0; y < 6; ++y)
    for (int x = 0; x < 8; ++x) gradient(y, x) = cv::Vec3b(static_cast<uint8_t>(30 * x), static_cast<uint8_t>(40 * y), 90);
  fs::remove(dir / "frame-000001.color.png");
  writeTextFile(dir / "frame-000001.color.jpg", testing::jpegWithExifOrientation(gradient, 3));
  expectInputError([&] { loadDataset(dir); },
                   {"frame 'frame-000001.color.jpg'", "frame-000001.color.jpg is turned by its EXIF orientation",
                    "frame-000001.depth.png is not"});
  // Orientation 1 (as stored) is no turn.
  writeTextFile(dir / "frame-000001.color.jpg", testing::jpegWithExifOrientation(gradient, 1));
  EXPECT_EQ(loadDataset(dir).frames.size(), 2u);
}

// Found by an outside probe: with both a PNG and a JPEG the PNG was taken without a word; with the
// documented intrinsics, a half-size image had its principal point in a corner, or its depth map
// blamed.
TEST(BadInput, SevenScenesFramesWithTwoImagesOrAnotherSizeThanTheDocumentedCamera) {
  const auto dir = makeSevenScenes();
  writeImage(dir / "frame-000001.color.jpg", 8, 6);
  expectInputError([&] { loadDataset(dir); },
                   {"frame-000001.pose.txt", "two colour images, frame-000001.color.png and frame-000001.color.jpg"});
  fs::remove(dir / "frame-000001.color.jpg");
  fs::remove(dir / "camera-intrinsics.txt");  // the documented 585 px camera of 640 x 480 images
  expectInputError([&] { loadDataset(dir); },
                   {"frame-000000.color.png", "image is 8x6, but 7-Scenes' intrinsics are of 640x480 images"});
}

TEST(BadInput, MalformedPoses) {
  struct Case {
    std::string text, expected;
  };
  const std::vector<Case> cases = {
      {"1 0 0 0\n0 1 0 0\n0 0 1 0\n", "4x4"},
      {"1 0 0 0\n0 1 0\n0 0 1 0\n0 0 0 1\n", ":2: expected 4 numbers"},
      {"1 0 0 0\n0 1 0 0\n0 0 1 nan\n0 0 0 1\n", ":3: non-finite value"},
      {"1 0 0 0\n0 1 0 0\n0 0 1 x\n0 0 0 1\n", ":3: expected a number"},
      {"1 0 0 0x10\n0 1 0 0\n0 0 1 0\n0 0 0 1\n", ":1: expected a number for value 4, got '0x10'"},  // was 16
      {"1 0 0 1e308\n0 1 0 0\n0 0 1 0\n0 0 0 1\n", ":1: camera centre is 1e+308 from the origin"},  // was :4:
      {"1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 1 1\n", "last row"},
      {"1 0 0 0\n0 2 0 0\n0 0 1 0\n0 0 0 1\n", "not orthonormal"},
      {"1 0 0 0\n0 1 0 0\n0 0 -1 0\n0 0 0 1\n", "rotation is a reflection (det -1): an axis is flipped"},
  };
  for (const auto& bad : cases) {
    SCOPED_TRACE(bad.text);
    const auto dir = makeSevenScenes();
    writeTextFile(dir / "frame-000001.pose.txt", bad.text);
    expectInputError([&] { loadDataset(dir); }, {"frame-000001.pose.txt", bad.expected});
  }
}

TEST(BadInput, SevenScenesTextFormsAreAccepted) {
  const auto dir = makeSevenScenes();
  // The original 7-Scenes writing: leading spaces, tabs, trailing tab, CRLF, e-001 exponents.
  writeTextFile(dir / "frame-000001.pose.txt",
                "  1.0000000e+000\t  0.0000000e+000\t  0.0000000e+000\t -5.0000000e-001\t\r\n"
                "  0.0000000e+000\t  1.0000000e+000\t  0.0000000e+000\t  2.5000000e-001\t\r\n"
                "  0.0000000e+000\t  0.0000000e+000\t  1.0000000e+000\t  1.0000000e+000\t\r\n"
                "  0.0000000e+000\t  0.0000000e+000\t  0.0000000e+000\t  1.0000000e+000\t\r\n");
  const Scene scene = loadDataset(dir);
  EXPECT_EQ(scene.frames[1].camera_to_world.t, Eigen::Vector3d(-0.5, 0.25, 1.0));
}

TEST(BadInput, MissingAndUnreadableImages) {
  auto dir = makeSevenScenes();
  fs::remove(dir / "frame-000001.color.png");
  expectInputError([&] { loadDataset(dir); }, {"frame-000001.pose.txt", "no colour image"});
  dir = makeSevenScenes();
  writeTextFile(dir / "frame-000001.color.png", "this is not a PNG");
  expectInputError([&] { loadDataset(dir); }, {"frame-000001.color.png", "cannot decode"});
}

TEST(BadInput, DepthOfWrongSize) {
  const auto dir = makeSevenScenes();
  ASSERT_TRUE(cv::imwrite((dir / "frame-000001.depth.png").string(), cv::Mat1w(3, 4, uint16_t(1000))));
  const Scene scene = loadDataset(dir);
  expectInputError([&] { readDepthMetres(scene.frames[1]); }, {"frame-000001.depth.png", "4x3", "8x6"});
}

TEST(BadInput, BadIntrinsicsFile) {
  const auto dir = makeSevenScenes();
  writeTextFile(dir / "camera-intrinsics.txt", "5 0 3.5\n0 5\n0 0 1\n");
  expectInputError([&] { loadDataset(dir); }, {"camera-intrinsics.txt:2"});
  // A link to no file took the default intrinsics without a word (an outside probe).
  fs::remove(dir / "camera-intrinsics.txt");
  fs::create_symlink(dir / "nowhere.txt", dir / "camera-intrinsics.txt");
  expectInputError([&] { loadDataset(dir); }, {"camera-intrinsics.txt", "not found"});
}

TEST(BadInput, SequenceLayoutSplitNamesMissingSequence) {
  const auto dir = testing::makeTempDir("ffloc-bad-seq");
  writeImage(dir / "seq-01/frame-000000.color.png", 640, 480);  // the size 7-Scenes intrinsics are for
  writeTextFile(dir / "seq-01/frame-000000.pose.txt", kIdentityPose);
  writeTextFile(dir / "TrainSplit.txt", "sequence1\r\n");
  writeTextFile(dir / "TestSplit.txt", "sequence1\r\n");
  expectInputError([&] { loadDataset(dir); }, {"TestSplit.txt:1", "both"});
  writeTextFile(dir / "TestSplit.txt", "sequence7\r\n");
  expectInputError([&] { loadDataset(dir); }, {"TestSplit.txt:1", "seq-07"});
  writeTextFile(dir / "TestSplit.txt", "");
  const Scene scene = loadDataset(dir);  // an empty split reads fine ...
  EXPECT_EQ(scene.mappingIndices().size(), 1u);
  expectInputError([&] { requireSplits(scene); }, {dir.string(), "split 'query' is empty"});  // ... but cannot be evaluated
}

TEST(BadInput, SplitFiles) {
  const auto dir = makeSevenScenes();
  writeTextFile(dir / "split_mapping.txt", "frame-000000.color.png\n");
  writeTextFile(dir / "split_query.txt", "# queries\n./frame-000001.color.png\n");
  Scene scene = loadDataset(dir);
  EXPECT_EQ(scene.frames[0].split, Split::kMapping);
  EXPECT_EQ(scene.frames[1].split, Split::kQuery);
  writeTextFile(dir / "split_query.txt", "frame-000001.color.png\nframe-000009.color.png\n");
  expectInputError([&] { loadDataset(dir); }, {"split_query.txt:2", "frame-000009.color.png"});
  writeTextFile(dir / "split_query.txt", "frame-000000.color.png\n");
  expectInputError([&] { loadDataset(dir); }, {"split_query.txt:1", "already listed in split_mapping.txt:1"});
  fs::remove(dir / "split_query.txt");
  scene = loadDataset(dir);
  EXPECT_EQ(scene.frames[1].split, Split::kUnassigned);
  expectInputError([&] { requireSplits(scene); },
                   {"split 'query' is empty (split_mapping.txt lists 1 frame(s); split files replace the dataset's own "
                    "split, and a frame neither lists is in none)"});
  // An empty query list alone: it named the mapping split, and no file.
  fs::remove(dir / "split_mapping.txt");
  writeTextFile(dir / "split_query.txt", "");
  expectInputError([&] { requireSplits(loadDataset(dir)); },
                   {"split 'mapping' is empty (split_query.txt lists 0 frame(s); split files replace"});
}

TEST(BadInput, UnknownFormat) {
  const auto dir = testing::makeTempDir("ffloc-bad-empty");
  expectInputError([&] { detectDatasetFormat(dir); },
                   {dir.string(), "unknown dataset format", "manifest.json", "transforms.json", "images.txt",
                    "gt_dense_cameras", "dataset_train.txt", "pose.txt"});
  expectInputError([&] { loadDataset(dir / "nope"); }, {"nope", "not found"});
  expectInputError([&] { loadDataset(dir, "blender"); }, {"unknown dataset format 'blender'"});
}

fs::path makeColmap() {
  const auto dir = testing::makeTempDir("ffloc-bad-colmap");
  writeTextFile(dir / "sparse/0/cameras.txt", "# comment\n1 PINHOLE 8 6 5 5 4 3\n");
  writeTextFile(dir / "sparse/0/images.txt",
                "# comment\n1 1 0 0 0 0 0 0 1 a.png\n1.5 2.5 7 3.5 3.5 -1\n2 1 0 0 0 1 0 0 1 b.png\n\n");
  writeTextFile(dir / "sparse/0/points3D.txt", "7 0 0 1 255 255 255 0.1 1 0\n");
  writeImage(dir / "images/a.png", 8, 6);
  writeImage(dir / "images/b.png", 8, 6);
  return dir;
}

TEST(BadInput, ColmapTinyModelReads) {
  const Scene scene = loadDataset(makeColmap());
  ASSERT_EQ(scene.frames.size(), 2u);
  EXPECT_EQ(scene.frames[1].name, "images/b.png");
  EXPECT_EQ(scene.frames[1].camera_to_world.centre(), Eigen::Vector3d(-1, 0, 0));  // world-to-camera inverted
  EXPECT_EQ(scene.frames[0].intrinsics.cx, 3.5);
  ASSERT_EQ(scene.points.size(), 1u);
  ASSERT_EQ(scene.points[0].observations.size(), 1u);
  EXPECT_EQ(scene.points[0].observations[0].pixel, Eigen::Vector2d(1.0, 2.0));
}

TEST(BadInput, ColmapCameraModelsMapToOpenCv) {
  const auto dir = makeColmap();
  writeTextFile(dir / "sparse/0/cameras.txt",
                "1 SIMPLE_PINHOLE 8 6 5 4 3\n2 PINHOLE 8 6 5 6 4 3\n3 SIMPLE_RADIAL 8 6 5 4 3 0.1\n"
                "4 RADIAL 8 6 5 4 3 0.1 0.2\n5 OPENCV 8 6 5 6 4 3 0.1 0.2 0.003 0.004\n");
  std::string images;
  for (int id = 1; id <= 5; ++id) {
    writeImage(dir / "images" / (std::to_string(id) + ".png"), 8, 6);
    images += std::to_string(id) + " 1 0 0 0 0 0 0 " + std::to_string(id) + " " + std::to_string(id) + ".png\n\n";
  }
  writeTextFile(dir / "sparse/0/images.txt", images);
  fs::remove(dir / "sparse/0/points3D.txt");
  const Scene scene = loadDataset(dir);
  ASSERT_EQ(scene.frames.size(), 5u);
  const std::vector<std::vector<double>> distortion = {
      {}, {}, {0.1, 0, 0, 0}, {0.1, 0.2, 0, 0}, {0.1, 0.2, 0.003, 0.004}};
  for (size_t i = 0; i < 5; ++i) {
    const Intrinsics& K = scene.frames[i].intrinsics;
    EXPECT_EQ(K.fx, 5.0);
    EXPECT_EQ(K.fy, i == 1 || i == 4 ? 6.0 : 5.0);
    EXPECT_EQ(K.cx, 3.5);
    EXPECT_EQ(K.cy, 2.5);
    EXPECT_EQ(K.distortion, distortion[i]) << i;
  }
}

TEST(BadInput, ColmapErrors) {
  auto dir = makeColmap();
  writeTextFile(dir / "sparse/0/cameras.txt", "# comment\n1 FOV 8 6 5 5 4 3 0.1\n");
  expectInputError([&] { loadDataset(dir); }, {"cameras.txt:2", "'FOV'"});
  dir = makeColmap();
  writeTextFile(dir / "sparse/0/cameras.txt", "1 PINHOLE 8 6 5 5 4\n");
  expectInputError([&] { loadDataset(dir); }, {"cameras.txt:1", "4 parameters"});
  dir = makeColmap();
  fs::remove(dir / "images/b.png");
  expectInputError([&] { loadDataset(dir); }, {"images.txt:4", "b.png", "not found"});
  dir = makeColmap();
  writeTextFile(dir / "sparse/0/points3D.txt", "7 0 0 1 255 255 255 0.1 1 4\n");
  expectInputError([&] { loadDataset(dir); }, {"points3D.txt:1", "POINT2D_IDX 4"});
  dir = makeColmap();
  writeTextFile(dir / "sparse/0/images.txt", "1 1 0 0 0 0 0 0 2 a.png\n\n");
  expectInputError([&] { loadDataset(dir); }, {"images.txt:1", "CAMERA_ID 2"});
  dir = makeColmap();
  writeTextFile(dir / "sparse/0/images.txt", "1 0 0 0 0 0 0 0 1 a.png\n\n");
  expectInputError([&] { loadDataset(dir); }, {"images.txt:1", "quaternion"});
}

// Found by an outside probe: a NaN translation was called a quaternion problem; a byte order
// mark turned the comment line it starts into "expected an integer for CAMERA_ID"; an image
// after the first of its size that was another size, or not an image, passed the reader and
// convert-dataset, whose copy its own reader then refused.
TEST(BadInput, ColmapTranslationsByteOrderMarksAndEveryImageAreChecked) {
  auto dir = makeColmap();
  writeTextFile(dir / "sparse/0/images.txt", "1 1 0 0 0 0 NaN 0 1 a.png\n\n");
  expectInputError([&] { loadDataset(dir); }, {"images.txt:1", "TY is not finite"});
  dir = makeColmap();
  writeTextFile(dir / "sparse/0/cameras.txt", "\xEF\xBB\xBF# comment\n1 PINHOLE 8 6 5 5 4 3\n");
  EXPECT_EQ(loadDataset(dir).frames.size(), 2u);
  dir = makeColmap();
  writeImage(dir / "images/b.png", 6, 8);
  expectInputError([&] { loadDataset(dir); }, {"frame 'images/b.png'", "the intrinsics are for a 8x6 image", "is 6x8"});
  // Stored at the claimed size but turned by its EXIF orientation: the check after the first
  // image of a size took the stored size.
  dir = makeColmap();
  writeTextFile(dir / "images/b.png", testing::jpegWithExifOrientation(cv::Mat3b(6, 8, cv::Vec3b(9, 9, 9)), 6));
  expectInputError([&] { loadDataset(dir); }, {"frame 'images/b.png'", "the intrinsics are for a 8x6 image", "is 6x8"});
  dir = makeColmap();
  writeTextFile(dir / "images/b.png", "not an image");
  expectInputError([&] { loadDataset(dir); }, {"frame 'images/b.png'", "b.png", "cannot decode"});
}

fs::path makeNerf(const std::string& frame_extra = "", const std::string& top_extra = "") {
  const auto dir = testing::makeTempDir("ffloc-bad-nerf");
  writeImage(dir / "train/r_0.png", 8, 6);
  writeTextFile(dir / "transforms_train.json",
                R"({"camera_angle_x": 1.0)" + top_extra + R"(, "frames": [{"file_path": "./train/r_0")" + frame_extra +
                    R"(, "transform_matrix": [[1,0,0,1],[0,1,0,2],[0,0,1,3],[0,0,0,1]]}]})");
  return dir;
}

TEST(BadInput, NerfBlenderStyleReads) {
  const Scene scene = loadDataset(makeNerf());
  ASSERT_EQ(scene.frames.size(), 1u);
  const Frame& frame = scene.frames[0];
  EXPECT_EQ(frame.name, "train/r_0.png");  // extension found
  EXPECT_EQ(frame.split, Split::kMapping);
  EXPECT_EQ(frame.intrinsics.width, 8);  // from the image, no w/h in the file
  EXPECT_NEAR(frame.intrinsics.fx, 4.0 / std::tan(0.5), 1e-12);
  EXPECT_EQ(frame.intrinsics.cx, 3.5);
  // OpenGL -> OpenCV: the camera's y and z axes flip.
  EXPECT_EQ(frame.camera_to_world.R.col(1), Eigen::Vector3d(0, -1, 0));
  EXPECT_EQ(frame.camera_to_world.R.col(2), Eigen::Vector3d(0, 0, -1));
}

TEST(BadInput, NerfPerFrameIntrinsicsOverrideTheFile) {
  const auto dir = testing::makeTempDir("ffloc-nerf-override");
  writeImage(dir / "a.jpg", 8, 6);
  writeImage(dir / "b.jpg", 8, 6);
  writeTextFile(dir / "transforms.json", R"({"fl_x": 10, "fl_y": 11, "cx": 4, "cy": 3, "w": 8, "h": 6, "k1": 0.1,
    "frames": [{"file_path": "a.jpg", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]},
               {"file_path": "b.jpg", "fl_x": 20, "cx": 5, "k1": 0,
                "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})");
  const Scene scene = loadDataset(dir);
  ASSERT_EQ(scene.frames.size(), 2u);
  const Intrinsics& a = scene.frames[0].intrinsics;
  const Intrinsics& b = scene.frames[1].intrinsics;
  EXPECT_EQ(a.fx, 10.0);
  EXPECT_EQ(a.cx, 3.5);
  EXPECT_EQ(a.distortion, (std::vector<double>{0.1, 0, 0, 0}));
  EXPECT_EQ(b.fx, 20.0);
  EXPECT_EQ(b.fy, 11.0);
  EXPECT_EQ(b.cx, 4.5);
  EXPECT_TRUE(b.distortion.empty());
  EXPECT_FALSE(scene.metric);
}

TEST(BadInput, NerfErrors) {
  auto dir = makeNerf();
  fs::remove(dir / "train/r_0.png");
  expectInputError([&] { loadDataset(dir); }, {"transforms_train.json", "frames[0].file_path", "not found"});
  expectInputError([&] { loadDataset(makeNerf(R"(, "camera_model": "OPENCV_FISHEYE")")); },
                   {"transforms_train.json", "frames[0].camera_model", "OPENCV_FISHEYE"});
  expectInputError([&] { loadDataset(makeNerf("", R"(, "fl_x": "big")")); }, {"transforms_train.json", "field 'fl_x'"});
  // "w" and "h" swapped passed, and a converted copy then failed its own reader.
  expectInputError([&] { loadDataset(makeNerf("", R"(, "w": 6, "h": 8)")); },
                   {"frame 'train/r_0.png'", "the intrinsics are for a 6x8 image, but", "r_0.png is 8x6"});
  // Found by an outside probe: with distortion given, the size, the focal length and the
  // principal point were judged through the distortion, and blamed on 'k2'; a focal length of 0
  // named no field.
  const std::string lens = R"(, "fl_x": 7.32, "k1": 0.05, "k2": -0.3)";  // folds an image twice as large
  EXPECT_EQ(loadDataset(makeNerf("", lens)).frames[0].intrinsics.distortion[1], -0.3);
  expectInputError([&] { loadDataset(makeNerf("", lens + R"(, "w": 16, "h": 12)")); },
                   {"the intrinsics are for a 16x12 image, but", "r_0.png is 8x6"});
  expectInputError([&] { loadDataset(makeNerf("", lens + R"(, "cx": 1e9)")); },
                   {"cx, cy: the principal point (1e+09"});
  expectInputError([&] { loadDataset(makeNerf("", R"(, "fl_x": 0, "k1": 0.05)")); },
                   {"transforms_train.json", "field 'fl_x': the focal length must be positive, got 0"});
  // A file of no frames read as a dataset of none (an outside probe).
  const fs::path none = testing::makeTempDir("ffloc-bad-nerf-empty");
  writeTextFile(none / "transforms.json", R"({"camera_angle_x": 1.0, "frames": []})");
  expectInputError([&] { loadDataset(none); }, {"the nerf dataset holds no frame"});
  // Degrees given by mistake read as radians: 40 gave a focal length 5.7 times too short.
  expectInputError([&] { loadDataset(makeNerf(R"(, "camera_angle_x": 40)")); },
                   {"transforms_train.json", "frames[0].camera_angle_x", "must be an angle in radians in (0, pi), got 40"});
}

fs::path makeStrecha() {
  const auto dir = testing::makeTempDir("ffloc-bad-strecha");
  writeImage(dir / "images/0000.jpg", 8, 6);
  writeTextFile(dir / "gt_dense_cameras/0000.jpg.camera",
                "5 0 3.5\n0 5 2.5\n0 0 1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 2 3\n8 6\n");
  return dir;
}

TEST(BadInput, StrechaErrors) {
  auto dir = makeStrecha();
  EXPECT_EQ(loadDataset(dir).frames[0].camera_to_world.t, Eigen::Vector3d(1, 2, 3));
  writeTextFile(dir / "gt_dense_cameras/0000.jpg.camera", "5 0 3.5\n0 5 2.5\n0 0 1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 2 3\n");
  expectInputError([&] { loadDataset(dir); }, {"0000.jpg.camera", "expected 9"});
  writeTextFile(dir / "gt_dense_cameras/0000.jpg.camera",
                "5 0 3.5\n0 5 2.5\n0 0 1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 2 3\n16 12\n");
  expectInputError([&] { loadDataset(dir); }, {"0000.jpg.camera:9:", "says the image is 16x12", "0000.jpg is 8x6"});
  writeTextFile(dir / "gt_dense_cameras/0000.jpg.camera",
                "5 0 3.5\n0 5 2.5\n0 0 1\n0 0 0\n1 0 0\n0 1 0\n0 1 1\n1 2 3\n8 6\n");
  expectInputError([&] { loadDataset(dir); }, {"0000.jpg.camera:5", "not orthonormal"});
}

TEST(BadInput, CambridgeReadsPosesAsCentreAndWorldToCameraRotation) {
  const auto dir = testing::makeTempDir("ffloc-cambridge");
  writeImage(dir / "seq1/frame00001.png", 96, 54);
  writeImage(dir / "seq2/frame00001.png", 96, 54);
  // A camera at C looking at the world origin: its world-to-camera rotation has rows
  // (x, y, z camera axes in world coordinates).
  const Eigen::Vector3d C(0, -2, 0);
  Eigen::Matrix3d R_world_to_camera;
  R_world_to_camera << 1, 0, 0,  //
      0, 0, -1,                  // camera y (down) = world -z
      0, 1, 0;                   // camera z (forward) = world +y, towards the origin
  const Eigen::Quaterniond q(R_world_to_camera);
  char line[256];
  std::snprintf(line, sizeof(line), "seq1/frame00001.png %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", C.x(), C.y(), C.z(),
                q.w(), q.x(), q.y(), q.z());
  writeTextFile(dir / "dataset_train.txt", std::string("Visual Landmark Dataset V1\nImageFile, Camera Position [X Y Z W P Q R]\n\n") + line);
  writeTextFile(dir / "dataset_test.txt", "Visual Landmark Dataset V1\nImageFile, Camera Position [X Y Z W P Q R]\n\n"
                                          "seq2/frame00001.png 0 0 -1 1 0 0 0\n");
  ASSERT_EQ(detectDatasetFormat(dir), "cambridge");
  Scene scene = loadDataset(dir);
  ASSERT_EQ(scene.frames.size(), 2u);
  const Frame& frame = scene.frames[0];
  EXPECT_EQ(frame.split, Split::kMapping);
  EXPECT_EQ(scene.frames[1].split, Split::kQuery);
  EXPECT_TRUE(frame.camera_to_world.centre().isApprox(C, 1e-9));
  // The origin projects to the principal point, a point above it (world +z) above it in the image.
  const Eigen::Vector3d origin = frame.camera_to_world.inverse() * Eigen::Vector3d::Zero();
  EXPECT_TRUE(frame.intrinsics.project(origin).isApprox(Eigen::Vector2d(47.5, 26.5), 1e-6));
  EXPECT_LT(frame.intrinsics.project(frame.camera_to_world.inverse() * Eigen::Vector3d(0, 0, 0.5)).y(), 26.5);
  EXPECT_NEAR(frame.intrinsics.fx, 1670.0 * 96 / 1920, 1e-9);  // default focal, scaled to the image

  // With the scene's reconstruction.nvm, each image gets its own focal length.
  writeTextFile(dir / "reconstruction.nvm", "NVM_V3\n\n2\nseq1/frame00001.jpg 1700 1 0 0 0 0 0 0 0 0\n"
                                            "seq2/frame00001.jpg 1600 1 0 0 0 0 0 0 0 0\n");
  scene = loadDataset(dir);
  EXPECT_NEAR(scene.frames[0].intrinsics.fx, 1700.0 * 96 / 1920, 1e-9);
  EXPECT_NEAR(scene.frames[1].intrinsics.fx, 1600.0 * 96 / 1920, 1e-9);

  writeTextFile(dir / "dataset_test.txt", "Visual Landmark Dataset V1\nImageFile, Camera Position [X Y Z W P Q R]\n\n"
                                          "seq2/frame00001.png 0 0 -1 1 0 0\n");
  expectInputError([&] { loadDataset(dir); }, {"dataset_test.txt:4"});
  writeTextFile(dir / "dataset_test.txt", "Visual Landmark Dataset V1\nImageFile, Camera Position [X Y Z W P Q R]\n\n"
                                          "seq2/frame00009.png 0 0 -1 1 0 0 0\n");
  expectInputError([&] { loadDataset(dir); }, {"dataset_test.txt:4", "frame00009.png", "not found"});

  // Without its three header lines a list lost its first three frames, without a word (found by
  // an outside probe); a malformed first entry is still refused, not skipped as a header.
  writeTextFile(dir / "dataset_test.txt", "seq2/frame00001.png 0 0 -1 1 0 0 0\n");
  ASSERT_EQ(loadDataset(dir).frames.size(), 2u);
  // Nor one written with commas, or naming an image that is not there.
  for (const char* malformed : {"seq2/frame00001.png 0 0 -1 1 0 0\n", "seq2/frame00001.png,0,0,-1,1,0,0,0\n",
                                "seq2/frame00009.png 0 0 -1 1 0 0\n"}) {
    writeTextFile(dir / "dataset_test.txt", malformed);
    expectInputError([&] { loadDataset(dir); }, {"dataset_test.txt:1", "expected 'ImageFile X Y Z W P Q R'"});
  }
}

}  // namespace
}  // namespace ffloc

namespace ffloc {
namespace {

// Found by the outside probe (a width cut to 32 bits, duplicate ids) and by the colmap fuzzer's
// review: every id and size is an integer checked before it narrows.
TEST(BadInput, ColmapIdsAndSizesAreCheckedIntegers) {
  auto dir = makeColmap();
  writeTextFile(dir / "sparse/0/cameras.txt", "1 PINHOLE 99999999999 6 5 5 4 3\n");
  expectInputError([&] { loadDataset(dir); }, {"cameras.txt:1", "WIDTH 99999999999 is outside [1, 1048576]"});
  writeTextFile(dir / "sparse/0/cameras.txt", "1 PINHOLE 8 0 5 5 4 3\n");
  expectInputError([&] { loadDataset(dir); }, {"cameras.txt:1", "HEIGHT 0"});
  dir = makeColmap();
  writeTextFile(dir / "sparse/0/points3D.txt", "7 0 0 1 255 255 255 0.1 1 0\n7 1 1 1 0 0 0 0.2 1 1\n");
  expectInputError([&] { loadDataset(dir); }, {"points3D.txt:2", "duplicate POINT3D_ID 7 (first on line 1)"});
  writeTextFile(dir / "sparse/0/points3D.txt", "7 0 0 1 255 255 255 0.1 1e300 0\n");
  expectInputError([&] { loadDataset(dir); }, {"points3D.txt:1", "IMAGE_ID", "1e300"});
  writeTextFile(dir / "sparse/0/points3D.txt", "7 0 0 1 255 255 255 0.1 1 0.5\n");
  expectInputError([&] { loadDataset(dir); }, {"points3D.txt:1", "POINT2D_IDX", "0.5"});
}

// The outside probe's 28 MB POINTS2D line took 751 MB as a vector of token strings; the reader
// now parses the line in place. Here a 1.2 MB line of 100,000 keypoints, read correctly.
TEST(BadInput, ColmapLongKeypointLineReads) {
  const auto dir = makeColmap();
  std::string keypoints;
  for (int i = 0; i < 100000; ++i) keypoints += std::to_string(i % 8) + " 2.5 " + (i == 99999 ? "7" : "-1") + " ";
  writeTextFile(dir / "sparse/0/images.txt",
                "1 1 0 0 0 0 0 0 1 a.png\n" + keypoints + "\n2 1 0 0 0 1 0 0 1 b.png\n\n");
  writeTextFile(dir / "sparse/0/points3D.txt", "7 0 0 1 255 255 255 0.1 1 99999\n");
  const Scene scene = loadDataset(dir);
  ASSERT_EQ(scene.points.size(), 1u);
  EXPECT_EQ(scene.points[0].observations[0].pixel, Eigen::Vector2d(7 - 0.5, 2.0));
}

// Parsed in place, the 28 MB line of 4 million short triples still took 288 MB as keypoints: one
// image's keypoints are bounded (a million, far beyond any extractor), and past the bound the
// line is refused before the rest of it is held.
TEST(BadInput, ColmapKeypointsPerImageAreBounded) {
  const auto dir = makeColmap();
  std::string keypoints;
  keypoints.reserve(6'000'010);
  for (int i = 0; i <= 1'000'000; ++i) keypoints += "1 1 -1 ";
  writeTextFile(dir / "sparse/0/images.txt", "1 1 0 0 0 0 0 0 1 a.png\n" + keypoints + "\n");
  expectInputError([&] { loadDataset(dir); }, {"images.txt:2", "more than 1000000 POINTS2D for image 'a.png'"});
}

// Sizes beyond what an int holds were converted to int before any check (undefined behaviour).
TEST(BadInput, StrechaAndNerfImageSizesAreCheckedBeforeConversion) {
  const auto dir = makeStrecha();
  writeTextFile(dir / "gt_dense_cameras/0000.jpg.camera",
                "5 0 3.5\n0 5 2.5\n0 0 1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 2 3\n1e30 6\n");
  expectInputError([&] { loadDataset(dir); }, {"0000.jpg.camera:9", "image size must be two whole numbers"});
  expectInputError([&] { loadDataset(makeNerf("", R"(, "w": 1e30, "h": 6)")); },
                   {"transforms_train.json", "field 'w'", "whole number of pixels"});
  expectInputError([&] { loadDataset(makeNerf("", R"(, "w": 8, "h": 4294967302)")); },
                   {"transforms_train.json", "field 'h'"});
  EXPECT_EQ(loadDataset(makeNerf("", R"(, "w": 8.0, "h": 6)")).frames[0].intrinsics.width, 8);
}

// A FIFO blocked the reader forever, a symbolic link loop escaped as std::filesystem's error
// (exit 3): both are now InputErrors naming the file.
TEST(BadInput, FifosAndSymbolicLinkLoopsAreRefused) {
  auto dir = makeSevenScenes();
  fs::remove(dir / "frame-000001.pose.txt");
  ASSERT_EQ(::mkfifo((dir / "frame-000001.pose.txt").c_str(), 0600), 0);
  expectInputError([&] { loadDataset(dir); }, {"frame-000001.pose.txt", "not a regular file"});

  dir = makeSevenScenes();
  fs::remove(dir / "frame-000001.color.png");
  ASSERT_EQ(::mkfifo((dir / "frame-000001.color.png").c_str(), 0600), 0);
  expectInputError([&] { loadDataset(dir); }, {"frame-000001.color.png", "not a regular file"});

  dir = makeSevenScenes();
  fs::remove(dir / "frame-000001.color.png");
  fs::create_symlink("frame-000001.color.png", dir / "frame-000001.color.png");
  expectInputError([&] { loadDataset(dir); }, {"frame-000001.color.png", "Too many levels of symbolic links"});

  dir = makeColmap();
  fs::remove(dir / "sparse/0/cameras.txt");
  fs::create_symlink("cameras.txt", dir / "sparse/0/cameras.txt");
  expectInputError([&] { loadDataset(dir); }, {"cameras.txt", "Too many levels of symbolic links"});

  const auto base = testing::makeTempDir("ffloc-bad-loop");
  fs::create_symlink("loop", base / "loop");
  expectInputError([&] { loadDataset(base / "loop"); }, {"loop", "Too many levels of symbolic links"});
  fs::create_directories(base / "manifest");
  fs::create_symlink("manifest.json", base / "manifest/manifest.json");
  expectInputError([&] { loadDataset(base / "manifest"); }, {"manifest.json", "Too many levels of symbolic links"});
}

// COLMAP's ids are unsigned: a negative one was read as any other key. -1 stays what COLMAP writes
// for a keypoint without a 3D point (makeColmap has one).
TEST(BadInput, ColmapIdsMustNotBeNegative) {
  struct Case {
    std::string file, text, expected;
  };
  const std::vector<Case> cases = {
      {"cameras.txt", "-1 PINHOLE 8 6 5 5 4 3\n", "cameras.txt:1: CAMERA_ID -1 is negative"},
      {"images.txt", "-1 1 0 0 0 0 0 0 1 a.png\n\n", "images.txt:1: IMAGE_ID -1 is negative"},
      {"images.txt", "1 1 0 0 0 0 0 0 -1 a.png\n\n", "images.txt:1: CAMERA_ID -1 is negative"},
      {"images.txt", "1 1 0 0 0 0 0 0 1 a.png\n1.5 2.5 -2\n", "images.txt:2: POINT3D_ID -2 is negative"},
      {"points3D.txt", "-7 0 0 1 255 255 255 0.1 1 0\n", "points3D.txt:1: POINT3D_ID -7 is negative"},
      {"points3D.txt", "7 0 0 1 255 255 255 0.1 -1 0\n", "points3D.txt:1: IMAGE_ID -1 is negative"},
  };
  for (const auto& bad : cases) {
    SCOPED_TRACE(bad.text);
    const auto dir = makeColmap();
    writeTextFile(dir / "sparse/0" / bad.file, bad.text);
    expectInputError([&] { loadDataset(dir); }, {bad.expected});
  }
}

// Every error of a .camera file names its line, as the other text readers' do; the image size and
// the camera centre named the file alone, or the dataset folder.
TEST(BadInput, StrechaErrorsNameTheLine) {
  const auto dir = makeStrecha();
  writeTextFile(dir / "gt_dense_cameras/0000.jpg.camera",
                "5 0 3.5\n0 5 2.5\n0 0 1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1e12 2 3\n8 6\n");
  expectInputError([&] { loadDataset(dir); }, {"0000.jpg.camera:8:", "camera centre is 1e+12 from the origin"});
  writeTextFile(dir / "gt_dense_cameras/0000.jpg.camera",
                "5 0 3.5\n0 -5 2.5\n0 0 1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 2 3\n8 6\n");
  expectInputError([&] { loadDataset(dir); }, {"0000.jpg.camera:2:", "the focal length must be positive"});  // was :9:
  writeTextFile(dir / "gt_dense_cameras/0000.jpg.camera",
                "5 0 3.5\n0 5 2.5\n0 0 1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 2 3\n\n8 6\n");
  fs::remove(dir / "images/0000.jpg");
  expectInputError([&] { loadDataset(dir); }, {"0000.jpg.camera:10:", "0000.jpg not found"});
}

// A distortion beyond any lens's (k1 = 1e10) was read as a lens, and NaN passed every reader that
// reads distortion; each now names its file and line or field. What is refused is what the model
// does over the image, not a coefficient's size: a narrow lens's k2 = -500 is read.
TEST(BadInput, DistortionBeyondAnyLensIsRefusedNamingFileAndField) {
  auto dir = makeColmap();
  writeTextFile(dir / "sparse/0/cameras.txt", "1 OPENCV 8 6 5 5 4 3 1e10 0 0 0\n");
  expectInputError([&] { loadDataset(dir); },
                   {"cameras.txt:1: k1 1e+10: moves the image corner (0, 0) by 3.2e+10 px, more than the 8x6 "
                    "image's diagonal (10 px)"});
  // Every digit read: six significant digits printed "100".
  writeTextFile(dir / "sparse/0/cameras.txt", "1 RADIAL 8 6 5 4 3 0.1 -100.0000001\n");
  expectInputError([&] { loadDataset(dir); }, {"cameras.txt:1: k1 0.1, k2 -100.0000001: moves the image corner"});
  writeTextFile(dir / "sparse/0/cameras.txt", "1 FULL_OPENCV 8 6 5 5 4 3 0 0 0 0 0 0 nan 0\n");
  expectInputError([&] { loadDataset(dir); }, {"cameras.txt:1: k5 nan: distortion coefficients must be finite"});
  // A 60 mm macro lens (fx = 8000 px on 640 x 480, here scaled to 8 x 6) and a wide-angle
  // rational-model calibration.
  writeTextFile(dir / "sparse/0/cameras.txt", "1 FULL_OPENCV 8 6 100 100 4 3 0 -500 0 0 300 0 0 0\n");
  EXPECT_EQ(loadDataset(dir).frames[0].intrinsics.distortion, (std::vector<double>{0, -500, 0, 0, 300, 0, 0, 0}));
  writeTextFile(dir / "sparse/0/cameras.txt", "1 FULL_OPENCV 8 6 4 4 4 3 25 10 0 0 0 25 15 0\n");
  EXPECT_EQ(loadDataset(dir).frames[0].intrinsics.distortion, (std::vector<double>{25, 10, 0, 0, 0, 25, 15, 0}));

  expectInputError([&] { loadDataset(makeNerf("", R"(, "k1": 1e10)")); },
                   {"transforms_train.json", "field 'k1': k1 1e+10: moves the image corner"});
  expectInputError([&] { loadDataset(makeNerf(R"(, "k1": 0.01, "p2": -300)")); },
                   {"transforms_train.json", "field 'frames[0].p2': k1 0.01, p2 -300: moves"});

  dir = makeStrecha();
  writeTextFile(dir / "gt_dense_cameras/0000.jpg.camera",
                "5 0 3.5\n0 5 2.5\n0 0 1\n0 0 1e10\n1 0 0\n0 1 0\n0 0 1\n1 2 3\n8 6\n");
  expectInputError([&] { loadDataset(dir); }, {"0000.jpg.camera:4: k3 1e+10: moves the image corner"});

  // Queries pass the same check, for the size of their image.
  Intrinsics query{500, 500, 319.5, 239.5, 0, 0, {320, 0, 0, 0}};
  expectInputError([&] { checkIntrinsicsFitImage(query, 640, 480); },
                   {"distortion: k1 320: moves the image corner (0, 0) by 8.1e+04 px, more than the 640x480 image's "
                    "diagonal (800 px)"});
  query.distortion = {std::numeric_limits<double>::infinity(), 0, 0, 0};
  expectInputError([&] { checkIntrinsicsFitImage(query, 640, 480); }, {"distortion: k1 inf: distortion coefficients must be finite"});
  query.fx = query.fy = 8000;
  query.distortion = {0, -500, 0, 0, 300};
  EXPECT_NO_THROW(checkIntrinsicsFitImage(query, 640, 480));
}

// A principal point or focal length in other units, beside a real lens's distortion, was blamed on
// the distortion (an outside probe: a manifest's cx 6400 for a 640 x 480 image gave "field
// 'cameras.phone.distortion': k1 0.05, k2 -0.08: moves the image corner (0, 0) by 7.3e+06 px").
TEST(BadInput, WrongPinholeIntrinsicsAreNamedNotTheDistortionBesideThem) {
  const auto dir = testing::makeTempDir("ffloc-bad-manifest");
  writeImage(dir / "a.png", 640, 480);
  const auto manifest = [&](const std::string& camera) {
    writeTextFile(dir / "manifest.json", R"({"format": "ffloc-manifest", "version": 1, "metric": true,
      "cameras": {"phone": {"width": 640, "height": 480, )" + camera + R"(, "distortion": [0.05, -0.08, 0, 0]}},
      "frames": [{"image": "a.png", "camera": "phone", "split": "query",
                  "camera_to_world": [[1,0,0,1],[0,1,0,2],[0,0,1,3],[0,0,0,1]]}]})");
    return dir;
  };
  EXPECT_EQ(loadDataset(manifest(R"("fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5)")).frames.size(), 1u);
  expectInputError([&] { loadDataset(manifest(R"("fx": 525, "fy": 525, "cx": 6400, "cy": 239.5)")); },
                   {"a.png", "intrinsics: cx, cy: the principal point (6400, 239.5) lies outside the 640x480 image"});
  // A focal length of 5 px is one a camera may have; the coefficients are named, and it beside them.
  expectInputError([&] { loadDataset(manifest(R"("fx": 5, "fy": 5, "cx": 319.5, "cy": 239.5)")); },
                   {"field 'cameras.phone.distortion'", "or the focal length is wrong: fx 5, fy 5 put that point 79.9 focal "
                    "lengths from the principal point"});
  expectInputError([&] { loadDataset(makeNerf("", R"(, "k1": 0.05, "k2": -0.08, "fl_x": 0.05, "fl_y": 0.05)")); },
                   {"transforms_train.json", "or the focal length is wrong"});
}

}  // namespace
}  // namespace ffloc
