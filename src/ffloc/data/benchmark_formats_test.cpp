// Hand-written samples of the benchmark formats, file by file as their descriptions give them,
// each with the conventions that trip people up (world-to-camera vs camera-to-world, quaternion
// order, pixel-centre convention, per-frame intrinsics, rigs). Every test checks geometry: the
// camera centre, and that a known 3D point lands on a known pixel.
#include <gtest/gtest.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "ffloc/core/testing/shared_data.h"
#include "ffloc/data/dataset.h"
#include "ffloc/data/depth.h"
#include "ffloc/data/scene_test_util.h"
#include "ffloc/io/pickle.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;
using testing::expectInputError;
using testing::writeTextFile;

// The camera of every sample: centre C = (1, 2, 3), rotated 90 degrees about the world y axis so
// it looks along world +x (camera-to-world R = Ry(90)). World-to-camera: R^T, t = -R^T C =
// (3, -2, -1); as a scalar-first quaternion (cos 45, 0, -sin 45, 0). Read scalar-last, or as
// camera-to-world, the same numbers give a camera elsewhere, looking elsewhere.
const Eigen::Vector3d kCentre(1, 2, 3);
constexpr const char* kWorldToCameraQuaternion = "0.7071067811865476 0 -0.7071067811865476 0";
constexpr const char* kWorldToCameraTranslation = "3 -2 -1";
constexpr const char* kCameraToWorldMatrix = "0 0 1 1\n0 1 0 2\n-1 0 0 3\n0 0 0 1\n";
constexpr const char* kWorldToCameraMatrix3x4 = "0 0 -1 3\n0 1 0 -2\n1 0 0 -1\n";

// 2 m ahead of the camera and 0.4 m along world +z, which is the camera's -x: with focal f it
// lands 0.2 f pixels left of the principal point.
const Eigen::Vector3d kWorldPoint = kCentre + Eigen::Vector3d(2, 0, 0.4);

void writeImage(const fs::path& path, int width, int height) {
  fs::create_directories(path.parent_path());
  ASSERT_TRUE(cv::imwrite(path.string(), cv::Mat(height, width, CV_8UC3, cv::Scalar(90, 120, 150))));
}

void writeDepthPng(const fs::path& path, int width, int height, uint16_t millimetres) {
  fs::create_directories(path.parent_path());
  cv::Mat1w depth(height, width, millimetres);
  depth(0, 0) = 65535;  // 7-Scenes' and RIO10's "no depth"
  ASSERT_TRUE(cv::imwrite(path.string(), depth));
}

const Frame& frameNamed(const Scene& scene, const std::string& name) {
  for (const Frame& frame : scene.frames)
    if (frame.name == name) return frame;
  ADD_FAILURE() << "no frame " << name;
  return scene.frames.front();
}

void expectRotatedCamera(const Frame& frame) {
  EXPECT_LT((frame.camera_to_world.centre() - kCentre).norm(), 1e-9) << frame.name;
  EXPECT_LT((frame.camera_to_world.R.col(2) - Eigen::Vector3d::UnitX()).norm(), 1e-9) << frame.name;
}

Eigen::Vector2d pixelOf(const Frame& frame, const Eigen::Vector3d& world) {
  return frame.intrinsics.project(frame.camera_to_world.inverse() * world);
}

fs::path mapFreeSample() {
  const fs::path dir = testing::makeTempDir("ffloc-mapfree") / "s00460";
  writeImage(dir / "seq0/frame_00000.jpg", 64, 48);
  writeImage(dir / "seq1/frame_00000.jpg", 64, 48);
  writeDepthPng(dir / "seq1/frame_00000.zed.png", 64, 48, 2500);
  writeTextFile(dir / "intrinsics.txt",
                "seq0/frame_00000.jpg 100 100 31.5 23.5 64 48\n"
                "seq1/frame_00000.jpg 120 110 30 22 64 48\n");
  // The reference image is the world origin, as in the benchmark.
  writeTextFile(dir / "poses.txt", "seq0/frame_00000.jpg 1 0 0 0 0 0 0\nseq1/frame_00000.jpg " +
                                       std::string(kWorldToCameraQuaternion) + " " + kWorldToCameraTranslation + "\n");
  return dir;
}

TEST(MapFree, WorldToCameraQuaternionsAndPerFrameIntrinsics) {
  const fs::path dir = mapFreeSample();
  ASSERT_EQ(detectDatasetFormat(dir), "mapfree");
  const Scene scene = loadDataset(dir);
  ASSERT_EQ(scene.frames.size(), 2u);
  const Frame& reference = frameNamed(scene, "seq0/frame_00000.jpg");
  const Frame& query = frameNamed(scene, "seq1/frame_00000.jpg");
  EXPECT_EQ(reference.split, Split::kMapping);
  EXPECT_EQ(query.split, Split::kQuery);
  EXPECT_TRUE(reference.camera_to_world.matrix().isIdentity(0));
  expectRotatedCamera(query);
  EXPECT_EQ(query.intrinsics.fx, 120);
  EXPECT_EQ(query.intrinsics.fy, 110);
  EXPECT_LT((pixelOf(query, kWorldPoint) - Eigen::Vector2d(30 - 0.2 * 120, 22)).norm(), 1e-9);
  ASSERT_TRUE(query.depth.has_value());
  EXPECT_FALSE(reference.depth.has_value());
  const cv::Mat1f depth = readDepthMetres(query);
  EXPECT_FLOAT_EQ(depth(10, 10), 2.5f);
  EXPECT_EQ(depth(0, 0), 0.0f);
}

TEST(MapFree, BadInputNamesFileAndLine) {
  const fs::path dir = mapFreeSample();
  writeTextFile(dir / "poses.txt", "seq0/frame_00000.jpg 1 0 0 0 0 0 0\n");
  expectInputError([&] { loadDataset(dir); }, {"intrinsics.txt:2:", "no pose for 'seq1/frame_00000.jpg'"});
  writeTextFile(dir / "poses.txt", "seq0/frame_00000.jpg 1 0 0 0 0 0 0\nseq1/frame_00000.jpg 2 0 0 0 3 -2 -1\n");
  expectInputError([&] { loadDataset(dir); }, {"poses.txt:2:", "quaternion (qw qx qy qz) has norm 2"});
  writeTextFile(dir / "poses.txt", "seq0/frame_00000.jpg 1 0 0 x 0 0 0\n");
  expectInputError([&] { loadDataset(dir); }, {"poses.txt:1:", "qz"});
  writeTextFile(dir / "poses.txt", "seq0/frame_00000.jpg 1 0 0 0 0 0 0\nseq1/frame_00000.jpg 1 0 0 0 0 0 0\n");
  writeTextFile(dir / "intrinsics.txt",
                "seq0/frame_00000.jpg 100 100 31.5 23.5 64 48\nseq1/frame_00000.jpg 100 100 319.5 239.5 640 480\n");
  expectInputError([&] { loadDataset(dir); }, {"intrinsics.txt:2:", "says the image is 640x480", "is 64x48"});
}

TEST(AceLayout, FocalOnlyAndMatrixCalibrationWithCameraToWorldPoses) {
  const fs::path dir = testing::makeTempDir("ffloc-ace") / "Cambridge_ShopFacade";
  // ACE's 7-Scenes naming in train/, DSAC*'s Cambridge naming (x.png, x.txt) in test/.
  writeImage(dir / "train/rgb/seq-01-frame-000000.color.png", 64, 48);
  writeTextFile(dir / "train/poses/seq-01-frame-000000.pose.txt", "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
  writeTextFile(dir / "train/calibration/seq-01-frame-000000.calibration.txt", "100\n");
  writeDepthPng(dir / "train/depth/seq-01-frame-000000.depth.png", 64, 48, 1200);
  writeImage(dir / "test/rgb/seq1_frame00001.png", 64, 48);
  writeTextFile(dir / "test/poses/seq1_frame00001.txt", kCameraToWorldMatrix);
  writeTextFile(dir / "test/calibration/seq1_frame00001.txt", "120 0 30\n0 110 22\n0 0 1\n");
  ASSERT_EQ(detectDatasetFormat(dir), "ace");
  const Scene scene = loadDataset(dir);
  ASSERT_EQ(scene.frames.size(), 2u);
  const Frame& train = frameNamed(scene, "train/rgb/seq-01-frame-000000.color.png");
  const Frame& test = frameNamed(scene, "test/rgb/seq1_frame00001.png");
  EXPECT_EQ(train.split, Split::kMapping);
  EXPECT_EQ(test.split, Split::kQuery);
  // A focal length alone puts the principal point at the image centre.
  EXPECT_EQ(train.intrinsics.cx, 31.5);
  EXPECT_EQ(train.intrinsics.cy, 23.5);
  EXPECT_LT((pixelOf(train, Eigen::Vector3d(0, 0, 2)) - Eigen::Vector2d(31.5, 23.5)).norm(), 1e-9);
  ASSERT_TRUE(train.depth.has_value());
  EXPECT_FLOAT_EQ(readDepthMetres(train)(5, 5), 1.2f);
  expectRotatedCamera(test);
  EXPECT_LT((pixelOf(test, kWorldPoint) - Eigen::Vector2d(30 - 0.2 * 120, 22)).norm(), 1e-9);

  fs::remove(dir / "test/poses/seq1_frame00001.txt");
  expectInputError([&] { loadDataset(dir); }, {"seq1_frame00001.png", "no poses file seq1_frame00001.*"});
}

fs::path rio10Sample() {
  const fs::path dir = testing::makeTempDir("ffloc-rio10") / "seq02";
  const std::string camera = "camera_intrinsics:\n  height: 64\n  width: 48\n  model: [100, 110, 23.5, 31.5]\n";
  for (const std::string sequence : {"seq02_01", "seq02_02", "seq02_03"}) {
    writeTextFile(dir / sequence / "camera.yaml", camera);
    writeImage(dir / sequence / "frame-000000.color.jpg", 48, 64);
    writeDepthPng(dir / sequence / "frame-000000.rendered.depth.png", 48, 64, 3000);
  }
  writeTextFile(dir / "seq02_01/frame-000000.pose.txt", "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
  writeTextFile(dir / "seq02_02/frame-000000.pose.txt", kCameraToWorldMatrix);
  return dir;  // seq02_03 is a hidden test sequence: no poses
}

TEST(Rio10, TrainingValidationAndHiddenSequences) {
  const fs::path dir = rio10Sample();
  ASSERT_EQ(detectDatasetFormat(dir), "rio10");
  const Scene scene = loadDataset(dir);
  ASSERT_EQ(scene.frames.size(), 2u);
  const Frame& train = frameNamed(scene, "seq02_01/frame-000000.color.jpg");
  const Frame& validation = frameNamed(scene, "seq02_02/frame-000000.color.jpg");
  EXPECT_EQ(train.split, Split::kMapping);
  EXPECT_EQ(validation.split, Split::kQuery);
  EXPECT_EQ(validation.intrinsics.width, 48);  // portrait frames
  EXPECT_EQ(validation.intrinsics.height, 64);
  expectRotatedCamera(validation);
  EXPECT_LT((pixelOf(validation, kWorldPoint) - Eigen::Vector2d(23.5 - 0.2 * 100, 31.5)).norm(), 1e-9);
  const cv::Mat1f depth = readDepthMetres(validation);
  EXPECT_FLOAT_EQ(depth(3, 3), 3.0f);
  EXPECT_EQ(depth(0, 0), 0.0f);

  writeImage(dir / "seq02_02/frame-000001.color.jpg", 48, 64);
  expectInputError([&] { loadDataset(dir); }, {"frame-000001.color.jpg", "no pose frame-000001.pose.txt beside it"});
  fs::remove(dir / "seq02_02/frame-000001.color.jpg");
  writeImage(dir / "seq02_02/frame-000000.color.jpg", 64, 48);
  expectInputError([&] { loadDataset(dir); }, {"camera.yaml:4:", "says the image is 48x64"});
}

TEST(Rio10, TheAuthorsIntrinsicsTxtBesideTheSceneFoldersWinsOverCameraYaml) {
  const fs::path dir = rio10Sample();
  // As in their repository's data/: one line per sequence, fx fy cx cy; the size is the images'.
  fs::remove(dir / "seq02_02/camera.yaml");
  writeTextFile(dir.parent_path() / "intrinsics.txt", "seq02_01 90 90 23.5 31.5\nseq02_02 120 110 23.5 31.5\n");
  ASSERT_EQ(detectDatasetFormat(dir), "rio10");
  Scene scene = loadDataset(dir);
  const Frame& validation = frameNamed(scene, "seq02_02/frame-000000.color.jpg");
  EXPECT_EQ(validation.intrinsics.width, 48);
  EXPECT_EQ(validation.intrinsics.height, 64);
  expectRotatedCamera(validation);
  EXPECT_LT((pixelOf(validation, kWorldPoint) - Eigen::Vector2d(23.5 - 0.2 * 120, 31.5)).norm(), 1e-9);
  EXPECT_EQ(frameNamed(scene, "seq02_01/frame-000000.color.jpg").intrinsics.fx, 90);

  // A sequence the file does not list keeps its camera.yaml; one in the scene folder comes first.
  writeTextFile(dir.parent_path() / "intrinsics.txt", "seq02_02 120 110 23.5 31.5\n");
  scene = loadDataset(dir);
  EXPECT_EQ(frameNamed(scene, "seq02_01/frame-000000.color.jpg").intrinsics.fx, 100);
  writeTextFile(dir / "intrinsics.txt", "seq02_02 80 80 23.5 31.5\n");
  EXPECT_EQ(frameNamed(loadDataset(dir), "seq02_02/frame-000000.color.jpg").intrinsics.fx, 80);
}

TEST(Rio10, BadIntrinsicsTxtAndDepthOfAnotherSizeNameTheirFiles) {
  const fs::path dir = rio10Sample();
  fs::remove(dir / "seq02_02/camera.yaml");
  writeTextFile(dir / "intrinsics.txt", "seq02_01 100 110 23.5 31.5\nseq02_02 120 110 23.5\n");
  expectInputError([&] { loadDataset(dir); }, {"intrinsics.txt:2:", "expected 'seqXX_YY fx fy cx cy', found 4 values"});
  writeTextFile(dir / "intrinsics.txt", "seq02_01 100 110 23.5 31.5\n");
  expectInputError([&] { loadDataset(dir); }, {"seq02_02: no camera: no camera.yaml in it", "intrinsics.txt has no line for it"});
  // The authors' evaluator scales the intrinsics to a smaller depth map; ffloc needs depth in the
  // image's pixel grid and says so rather than misreading it.
  writeTextFile(dir / "intrinsics.txt", "seq02_01 100 110 23.5 31.5\nseq02_02 120 110 23.5 31.5\n");
  writeDepthPng(dir / "seq02_02/frame-000000.rendered.depth.png", 24, 32, 3000);
  const Scene scene = loadDataset(dir);
  expectInputError([&] { readDepthMetres(frameNamed(scene, "seq02_02/frame-000000.color.jpg")); },
                   {"frame-000000.rendered.depth.png", "depth image is 24x32 but the frame's image is 48x64"});
}

// The authors' split file as Python 3.11 writes it: pickle.dumps({'train': [...], 'val': [...],
// 'test': [...], 'train_idx': [0], 'val_idx': [2], 'test_idx': [1]}, protocol=2).
constexpr char kIndoor6SplitsProtocol2[] =
    "\x80\x02}q\x00(X\x05\x00\x00\x00trainq\x01]q\x02X\x16\x00\x00\x00image-000000.color.jpgq\x03"
    "aX\x03\x00\x00\x00valq\x04]q\x05X\x14\x00\x00\x00other-0002.color.jpgq\x06" "aX\x04\x00\x00"
    "\x00testq\x07]q\x08X\x16\x00\x00\x00image-000001.color.jpgq\x09" "aX\x09\x00\x00\x00train_"
    "idxq\x0a]q\x0bK\x00" "aX\x07\x00\x00\x00val_idxq\x0c]q\x0dK\x02" "aX\x08\x00\x00\x00test_i"
    "dxq\x0e]q\x0fK\x01" "au.";

// The same lists with protocol 4 (FRAME, SHORT_BINUNICODE, MEMOIZE), each *_idx a numpy int64
// array as numpy pickles one (numpy.core.multiarray._reconstruct, BUILD with dtype and raw bytes).
constexpr char kIndoor6SplitsProtocol4[] =
    "\x80\x04\x95z\x01\x00\x00\x00\x00\x00\x00}\x94(\x8c\x05train\x94]\x94\x8c\x16image-000000."
    "color.jpg\x94" "a\x8c\x03val\x94]\x94\x8c\x14other-0002.color.jpg\x94" "a\x8c\x04test\x94]"
    "\x94\x8c\x16image-000001.color.jpg\x94" "a\x8c\x09train_idx\x94\x8c\x15numpy.core.multiarr"
    "ay\x94\x8c\x0c_reconstruct\x94\x93\x94\x8c\x05numpy\x94\x8c\x07ndarray\x94\x93\x94K\x00\x85"
    "\x94" "C\x01" "b\x94\x87\x94R\x94(K\x01K\x01\x85\x94h\x0e\x8c\x05" "dtype\x94\x93\x94\x8c\x02"
    "i8\x94\x89\x88\x87\x94R\x94(K\x03\x8c\x01<\x94NNNJ\xff\xff\xff\xffJ\xff\xff\xff\xffK\x00t\x94"
    "b\x89" "C\x08\x00\x00\x00\x00\x00\x00\x00\x00\x94t\x94" "b\x8c\x07val_idx\x94h\x0dh\x10h\x11"
    "h\x12\x87\x94R\x94(K\x01K\x01\x85\x94h\x17h\x18\x89\x88\x87\x94R\x94h\x1c" "b\x89" "C\x08\x02"
    "\x00\x00\x00\x00\x00\x00\x00\x94t\x94" "b\x8c\x08test_idx\x94h\x0dh\x10h\x11h\x12\x87\x94R"
    "\x94(K\x01K\x01\x85\x94h\x17h\x18\x89\x88\x87\x94R\x94h\x1c" "b\x89" "C\x08\x01\x00\x00\x00"
    "\x00\x00\x00\x00\x94t\x94" "bu.";

template <size_t N>
std::string bytesOf(const char (&literal)[N]) {
  return std::string(literal, N - 1);
}

// Three images, the third without the image-NNNNNN prefix (the authors' loader globs *.color.jpg).
fs::path indoor6Sample(const std::string& split_pickle) {
  const fs::path dir = testing::makeTempDir("ffloc-indoor6") / "scene3";
  const std::string stems[] = {"image-000000", "image-000001", "other-0002"};
  for (const std::string& stem : stems) {
    writeImage(dir / "images" / (stem + ".color.jpg"), 64, 48);
    // COLMAP-derived cameras: the principal point (32, 24) is the image centre in COLMAP pixels.
    // Token 5 is a number no loader of the authors reads, token 6 the original image's name.
    writeTextFile(dir / "images" / (stem + ".intrinsics.txt"), "64 48 100 32 24 0.013 IMG_2042.JPG\n");
  }
  writeTextFile(dir / "images/image-000000.pose.txt", "1 0 0 0\n0 1 0 0\n0 0 1 0\n");
  writeTextFile(dir / "images/image-000001.pose.txt", kWorldToCameraMatrix3x4);
  writeTextFile(dir / "images/other-0002.pose.txt", "1 0 0 0\n0 1 0 0\n0 0 1 0\n");
  writeTextFile(dir / "train_test_val.pkl", split_pickle);
  return dir;
}

void expectIndoor6Splits(const Scene& scene) {
  ASSERT_EQ(scene.frames.size(), 3u);
  EXPECT_EQ(frameNamed(scene, "images/image-000000.color.jpg").split, Split::kMapping);
  EXPECT_EQ(frameNamed(scene, "images/image-000001.color.jpg").split, Split::kQuery);
  EXPECT_EQ(frameNamed(scene, "images/other-0002.color.jpg").split, Split::kUnassigned);
}

TEST(Indoor6, WorldToCameraPosesColmapPixelCentresAndTheAuthorsSplitPickle) {
  const fs::path dir = indoor6Sample(bytesOf(kIndoor6SplitsProtocol2));
  ASSERT_EQ(detectDatasetFormat(dir), "indoor6");
  const Scene scene = loadDataset(dir);
  expectIndoor6Splits(scene);
  const Frame& test = frameNamed(scene, "images/image-000001.color.jpg");
  EXPECT_EQ(test.intrinsics.cx, 31.5);
  EXPECT_EQ(test.intrinsics.cy, 23.5);
  expectRotatedCamera(test);
  const Eigen::Vector2d seen(31.5 - 0.2 * 100, 23.5);
  EXPECT_LT((pixelOf(test, kWorldPoint) - seen).norm(), 1e-9);
  // Where the point is seen needs no undistorting: token 5 read as a radial k would move it 0.01 px.
  EXPECT_LT((undistortPixels(test.intrinsics, {seen})[0] - seen).norm(), 1e-9);
}

TEST(Indoor6, Protocol4SplitPickleWithNumpyIndices) {
  expectIndoor6Splits(loadDataset(indoor6Sample(bytesOf(kIndoor6SplitsProtocol4))));
}

TEST(Indoor6, ThirdPartySplitListsServeOnlyWithoutThePickle) {
  const fs::path dir = indoor6Sample(bytesOf(kIndoor6SplitsProtocol2));
  writeTextFile(dir / "scene3_train.txt", "image-000001.color.jpg\n");  // ignored beside the pickle
  expectIndoor6Splits(loadDataset(dir));
  fs::remove(dir / "train_test_val.pkl");
  writeTextFile(dir / "scene3_train.txt", "image-000000.color.jpg\n");
  writeTextFile(dir / "scene3_test.txt", "image-000001.color.jpg\n");
  writeTextFile(dir / "scene3_val.txt", "other-0002.color.jpg\n");
  expectIndoor6Splits(loadDataset(dir));
  writeTextFile(dir / "scene3_test.txt", "image-000009.color.jpg\n");
  expectInputError([&] { loadDataset(dir); }, {"scene3_test.txt:1:", "'image-000009.color.jpg' is not an image"});
}

TEST(Indoor6, BadInputNamesFileAndKeyOrLine) {
  const fs::path dir = indoor6Sample(bytesOf(kIndoor6SplitsProtocol2));
  const auto writeSplits = [&](const std::vector<std::string>& train, const std::vector<std::string>& test) {
    pickle::Writer splits;
    splits.op('}');
    splits.op('(');
    if (!train.empty()) {
      splits.text("train");
      splits.stringList(train);
    }
    splits.text("test");
    splits.stringList(test);
    splits.op('u');
    writeTextFile(dir / "train_test_val.pkl", splits.finish());
  };
  writeSplits({}, {"image-000001.color.jpg"});
  expectInputError([&] { loadDataset(dir); }, {"train_test_val.pkl: key 'train' is missing"});
  writeSplits({"image-000000.color.jpg"}, {"image-000009.color.jpg"});
  expectInputError([&] { loadDataset(dir); },
                   {"train_test_val.pkl: key 'test': 'image-000009.color.jpg' is not an image in", "images"});
  writeSplits({"image-000000.color.jpg"}, {"image-000000.color.jpg"});
  expectInputError([&] { loadDataset(dir); },
                   {"train_test_val.pkl: key 'test': 'image-000000.color.jpg' is in both the train and the test split"});
  pickle::Writer numbers;
  numbers.op('}');
  numbers.text("train");
  numbers.integerList({0});
  numbers.op('s');  // SETITEM
  writeTextFile(dir / "train_test_val.pkl", numbers.finish());
  expectInputError([&] { loadDataset(dir); }, {"train_test_val.pkl: key 'train' is not a list of strings"});
  writeTextFile(dir / "train_test_val.pkl", bytesOf(kIndoor6SplitsProtocol2).substr(0, 60));
  expectInputError([&] { loadDataset(dir); }, {"train_test_val.pkl: pickle offset", "truncated"});

  writeTextFile(dir / "train_test_val.pkl", bytesOf(kIndoor6SplitsProtocol2));
  writeTextFile(dir / "images/image-000001.intrinsics.txt", "64 48 100 32\n");
  expectInputError([&] { loadDataset(dir); }, {"image-000001.intrinsics.txt:1:", "expected 'W H f cx cy ...', found 4 values"});
  writeTextFile(dir / "images/image-000001.intrinsics.txt", "640 480 100 320 240\n");
  expectInputError([&] { loadDataset(dir); }, {"image-000001.intrinsics.txt:1:", "says the image is 640x480"});
  fs::remove(dir / "images/image-000001.pose.txt");
  expectInputError([&] { loadDataset(dir); }, {"image-000001.color.jpg", "no image-000001.pose.txt beside it"});
}

constexpr const char* kKaptureHeader = "# kapture format: 1.1\n";

// kapture's .depth: raw float32 metres, row-major; (0, 0) holds no depth.
void writeRawDepth(const fs::path& path, int width, int height, float metres) {
  fs::create_directories(path.parent_path());
  std::vector<float> depth(static_cast<size_t>(width) * height, metres);
  depth[0] = 0.0f;
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(depth.data()), static_cast<std::streamsize>(depth.size() * sizeof(float)));
}

fs::path kaptureSample() {
  const fs::path dir = testing::makeTempDir("ffloc-kapture") / "stairs";
  // mapping/: one RGB-D camera whose depth sensor shares its timestamps, identity pose.
  const fs::path mapping = dir / "mapping/sensors";
  writeTextFile(mapping / "sensors.txt", std::string(kKaptureHeader) +
                                             "# sensor_device_id, name, sensor_type, [sensor_params]+\n"
                                             "kinect_rgb, kinect, camera, PINHOLE, 64, 48, 100, 100, 32, 24\n"
                                             "kinect_depth, kinect, depth, PINHOLE, 64, 48, 100, 100, 32, 24\n");
  writeTextFile(mapping / "records_camera.txt", std::string(kKaptureHeader) + "0, kinect_rgb, seq-01/frame-000000.color.jpg\n");
  writeTextFile(mapping / "records_depth.txt", std::string(kKaptureHeader) + "0, kinect_depth, seq-01/frame-000000.depth\n");
  writeTextFile(mapping / "trajectories.txt", std::string(kKaptureHeader) + "0, kinect_rgb, 1, 0, 0, 0, 0, 0, 0\n");
  writeImage(mapping / "records_data/seq-01/frame-000000.color.jpg", 64, 48);
  writeRawDepth(mapping / "records_data/seq-01/frame-000000.depth", 64, 48, 1.75f);
  // query/: the trajectory gives the rig's world-to-device pose (rig centre (1, 2, 2.9)); rigs.txt
  // the rig-to-camera transform, whose translation +0.1 puts the camera at the rig's -x.
  const fs::path query = dir / "query/sensors";
  writeTextFile(query / "sensors.txt", std::string(kKaptureHeader) +
                                           "phone, , camera, SIMPLE_RADIAL, 64, 48, 120, 30.5, 22.5, 0.01\n");
  writeTextFile(query / "rigs.txt", std::string(kKaptureHeader) + "rig, phone, 1, 0, 0, 0, 0.1, 0, 0\n");
  writeTextFile(query / "records_camera.txt", std::string(kKaptureHeader) + "7, phone, query/0007.jpg\n");
  writeTextFile(query / "trajectories.txt",
                std::string(kKaptureHeader) + "7, rig, 0.7071067811865476, 0, -0.7071067811865476, 0, 2.9, -2, -1\n");
  writeImage(query / "records_data/query/0007.jpg", 64, 48);
  return dir;
}

TEST(Kapture, MappingAndQueryFoldersRigsDepthAndCornerPixelCentres) {
  const fs::path dir = kaptureSample();
  ASSERT_EQ(detectDatasetFormat(dir), "kapture");
  const Scene scene = loadDataset(dir);
  ASSERT_EQ(scene.frames.size(), 2u);
  const Frame& mapping = frameNamed(scene, "mapping/sensors/records_data/seq-01/frame-000000.color.jpg");
  const Frame& query = frameNamed(scene, "query/sensors/records_data/query/0007.jpg");
  EXPECT_EQ(mapping.split, Split::kMapping);
  EXPECT_EQ(query.split, Split::kQuery);
  // kapture's camera parameters are COLMAP's: (32, 24) is the centre of a 64x48 image.
  EXPECT_EQ(mapping.intrinsics.cx, 31.5);
  EXPECT_EQ(mapping.intrinsics.cy, 23.5);
  ASSERT_TRUE(mapping.depth.has_value());
  const cv::Mat1f depth = readDepthMetres(mapping);
  EXPECT_FLOAT_EQ(depth(20, 30), 1.75f);
  EXPECT_EQ(depth(0, 0), 0.0f);
  EXPECT_FALSE(query.depth.has_value());
  expectRotatedCamera(query);
  EXPECT_EQ(query.intrinsics.distortion, (std::vector<double>{0.01, 0, 0, 0}));
  EXPECT_LT((pixelOf(query, kWorldPoint) - Eigen::Vector2d(30 - 0.2 * 120, 22)).norm(), 1e-9);
}

TEST(Kapture, BadInputNamesFileAndLine) {
  const fs::path dir = kaptureSample();
  const fs::path query = dir / "query/sensors";
  writeTextFile(query / "sensors.txt", std::string(kKaptureHeader) + "phone, , camera, FOV, 64, 48, 120, 120, 32, 24, 0.9\n");
  expectInputError([&] { loadDataset(dir); }, {"sensors.txt:2:", "unsupported camera model 'FOV'"});
  // Without its name column the line's camera was skipped, and its images blamed instead.
  writeTextFile(query / "sensors.txt", std::string(kKaptureHeader) + "phone, camera, PINHOLE, 64, 48, 120, 120, 32, 24\n");
  expectInputError([&] { loadDataset(dir); }, {"sensors.txt:2:", "sensor type 'PINHOLE' is a camera model"});
  writeTextFile(query / "sensors.txt", std::string(kKaptureHeader) + "phone, , camera, PINHOLE, 640, 480, 120, 120, 32, 24\n");
  expectInputError([&] { loadDataset(dir); }, {"sensors.txt:2:", "says the image is 640x480", "is 64x48"});
  writeTextFile(query / "sensors.txt", std::string(kKaptureHeader) + "phone, , camera, PINHOLE, 64, 48, 120, 120, 32, 24\n");
  writeTextFile(query / "trajectories.txt", std::string(kKaptureHeader) + "7, rig, 0.5, 0, 0, 0, 0, 0, 0\n");
  expectInputError([&] { loadDataset(dir); }, {"trajectories.txt:2:", "has norm 0.5"});
  writeTextFile(query / "trajectories.txt", std::string(kKaptureHeader) + "8, rig, 1, 0, 0, 0, 0, 0, 0\n");
  expectInputError([&] { loadDataset(dir); },
                   {"records_camera.txt:2:", "no pose for image 'query/0007.jpg' (timestamp 7, device phone)"});
  // The last of two poses won, and the frame was scored against another frame's pose.
  writeTextFile(query / "trajectories.txt",
                std::string(kKaptureHeader) + "7, rig, 1, 0, 0, 0, 0, 0, 0\n7, rig, 1, 0, 0, 0, 5, 0, 0\n");
  expectInputError([&] { loadDataset(dir); }, {"trajectories.txt:3:", "a second pose for timestamp 7, device 'rig'"});
  // Found by an outside probe: a sensor placed in a rig twice took the last line's transform
  // silently, and a missing image was blamed on its camera's line in sensors.txt.
  writeTextFile(query / "trajectories.txt", std::string(kKaptureHeader) + "7, rig, 1, 0, 0, 0, 0, 0, 0\n");
  writeTextFile(query / "rigs.txt", std::string(kKaptureHeader) + "rig, phone, 1, 0, 0, 0, 0.1, 0, 0\n"
                                                                 "rig, phone, 1, 0, 0, 0, 5, 5, 5\n");
  expectInputError([&] { loadDataset(dir); }, {"rigs.txt:3:", "sensor 'phone' is placed in a rig again (first on line 2)"});
  writeTextFile(query / "rigs.txt", std::string(kKaptureHeader) + "rig, phone, 1, 0, 0, 0, 0.1, 0, 0\n");
  // A camera 1e300 from the origin was reported as a depth map of "another pose" where depth was
  // recorded (an outside probe), then at the image's line of records_camera.txt (another); named
  // at its trajectory's line now, as NaN there is.
  writeTextFile(dir / "mapping/sensors/trajectories.txt",
                std::string(kKaptureHeader) + "0, kinect_rgb, 1, 0, 0, 0, 1e300, 0, 0\n");
  expectInputError([&] { loadDataset(dir); }, {"trajectories.txt:2:", "device 'kinect_rgb': camera centre is 1e+300"});
  writeTextFile(dir / "mapping/sensors/trajectories.txt", std::string(kKaptureHeader) + "0, kinect_rgb, 1, 0, 0, 0, 0, 0, 0\n");
  fs::remove(query / "records_data/query/0007.jpg");
  expectInputError([&] { loadDataset(dir); }, {"records_camera.txt:2:", "0007.jpg not found"});
}

// Found by an outside probe: a half whose sensors.txt was lost, or whose records_camera.txt was
// emptied, read as no frames: the dataset was its other half alone, exit 0.
TEST(Kapture, AHalfWithoutCamerasOrImagesIsRefused) {
  const fs::path dir = kaptureSample();
  const fs::path mapping = dir / "mapping/sensors";
  writeTextFile(mapping / "records_camera.txt", std::string(kKaptureHeader));
  expectInputError([&] { loadDataset(dir); }, {"mapping/sensors/records_camera.txt", "lists no image"});
  fs::remove(mapping / "sensors.txt");
  expectInputError([&] { loadDataset(dir); }, {"mapping/sensors/sensors.txt", "not found"});
}

// ffloc reads registered depth only, whose sensor has its colour camera's intrinsics. Paired by
// size, a depth sensor of another resolution (an Azure Kinect's 640x576 beside 1280x720 colour)
// refused the whole dataset, and one of the image's size but another focal length was read as if
// in the image's grid.
TEST(Kapture, DepthGoesToTheImageWhoseCameraHasItsIntrinsics) {
  const fs::path dir = kaptureSample();
  const fs::path mapping = dir / "mapping/sensors";
  const std::string image = "mapping/sensors/records_data/seq-01/frame-000000.color.jpg";
  for (const std::string depth_sensor : {"kinect_depth, kinect, depth, PINHOLE, 32, 24, 50, 50, 16, 12\n",
                                         "kinect_depth, kinect, depth, PINHOLE, 64, 48, 90, 90, 32, 24\n"}) {
    writeTextFile(mapping / "sensors.txt", std::string(kKaptureHeader) +
                                               "kinect_rgb, kinect, camera, PINHOLE, 64, 48, 100, 100, 32, 24\n" +
                                               depth_sensor);
    EXPECT_FALSE(frameNamed(loadDataset(dir), image).depth.has_value()) << depth_sensor;
  }
  // A rig's camera of other intrinsics at the same instant goes without.
  writeTextFile(mapping / "sensors.txt", std::string(kKaptureHeader) +
                                             "kinect_rgb, kinect, camera, PINHOLE, 64, 48, 100, 100, 32, 24\n"
                                             "kinect_depth, kinect, depth, PINHOLE, 64, 48, 100, 100, 32, 24\n"
                                             "side, , camera, PINHOLE, 32, 24, 50, 50, 16, 12\n");
  writeTextFile(mapping / "records_camera.txt", std::string(kKaptureHeader) +
                                                    "0, kinect_rgb, seq-01/frame-000000.color.jpg\n0, side, side.jpg\n");
  writeTextFile(mapping / "trajectories.txt",
                std::string(kKaptureHeader) + "0, kinect_rgb, 1, 0, 0, 0, 0, 0, 0\n0, side, 1, 0, 0, 0, 1, 0, 0\n");
  writeImage(mapping / "records_data/side.jpg", 32, 24);
  const Scene scene = loadDataset(dir);
  EXPECT_TRUE(frameNamed(scene, image).depth.has_value());
  EXPECT_FALSE(frameNamed(scene, "mapping/sensors/records_data/side.jpg").depth.has_value());
}

// Two RGB-D cameras of one size on a rig: paired by size, both images took depth0's map and depth1's
// was dropped without a word. The sensors' poses tell which map is whose; without them the record
// is refused, naming both images.
TEST(Kapture, ARigOfTwoRgbdCamerasGivesEachImageItsOwnDepth) {
  const fs::path dir = kaptureSample();
  const fs::path mapping = dir / "mapping/sensors";
  const std::string intrinsics = "PINHOLE, 64, 48, 100, 100, 32, 24\n";
  writeTextFile(mapping / "sensors.txt", std::string(kKaptureHeader) + "cam0, , camera, " + intrinsics +
                                             "cam1, , camera, " + intrinsics + "depth0, , depth, " + intrinsics +
                                             "depth1, , depth, " + intrinsics);
  writeTextFile(mapping / "records_camera.txt", std::string(kKaptureHeader) + "0, cam0, cam0.jpg\n0, cam1, cam1.jpg\n");
  writeTextFile(mapping / "records_depth.txt", std::string(kKaptureHeader) + "0, depth0, depth0.depth\n0, depth1, depth1.depth\n");
  const std::string cam0_pose = "1, 0, 0, 0, 0, 0, 0\n", cam1_pose = "1, 0, 0, 0, -0.2, 0, 0\n";
  writeTextFile(mapping / "trajectories.txt",
                std::string(kKaptureHeader) + "0, cam0, " + cam0_pose + "0, cam1, " + cam1_pose);
  writeImage(mapping / "records_data/cam0.jpg", 64, 48);
  writeImage(mapping / "records_data/cam1.jpg", 64, 48);
  writeRawDepth(mapping / "records_data/depth0.depth", 64, 48, 1.0f);
  writeRawDepth(mapping / "records_data/depth1.depth", 64, 48, 2.0f);
  expectInputError([&] { loadDataset(dir); },
                   {"records_depth.txt:2:", "depth0.depth (sensor 'depth0') could be the depth of",
                    "cam0.jpg and ", "cam1.jpg of its timestamp", "the sensor has no pose"});

  // As ffloc's writer gives them, and as a rig gives them (depth1 beside cam1 on the rig).
  writeTextFile(mapping / "rigs.txt", std::string(kKaptureHeader) + "rig, depth1, " + cam1_pose);
  writeTextFile(mapping / "trajectories.txt", std::string(kKaptureHeader) + "0, cam0, " + cam0_pose + "0, cam1, " +
                                                  cam1_pose + "0, depth0, " + cam0_pose + "0, rig, " + cam0_pose);
  const Scene scene = loadDataset(dir);
  for (const auto& [camera, metres] : {std::pair{"cam0", 1.0f}, {"cam1", 2.0f}}) {
    const Frame& frame = frameNamed(scene, "mapping/sensors/records_data/" + std::string(camera) + ".jpg");
    ASSERT_TRUE(frame.depth.has_value()) << camera;
    EXPECT_FLOAT_EQ(readDepthMetres(frame)(20, 30), metres) << camera;
  }

  // A pose that is neither camera's puts the map in neither image's grid.
  writeTextFile(mapping / "rigs.txt", std::string(kKaptureHeader) + "rig, depth1, 1, 0, 0, 0, 0.5, 0, 0\n");
  expectInputError([&] { loadDataset(dir); },
                   {"records_depth.txt:3:", "depth1.depth (sensor 'depth1') has the intrinsics of", "cam0.jpg and ",
                    "cam1.jpg of its timestamp but another pose"});
  // Two sensors of one image's intrinsics and pose at one instant: the second map was dropped.
  writeTextFile(mapping / "rigs.txt", std::string(kKaptureHeader) + "rig, depth1, " + cam0_pose);
  expectInputError([&] { loadDataset(dir); },
                   {"records_depth.txt:3:", "depth1.depth (sensor 'depth1') belongs to", "cam0.jpg, which has the depth map of line 2"});
}

// The depth file is the sensor's width x height of float32: one of another size is corrupt (read as
// the image's size, its rows were sheared).
TEST(Kapture, ADepthFileOfAnotherSizeThanItsSensorIsRefused) {
  const fs::path dir = kaptureSample();
  writeRawDepth(dir / "mapping/sensors/records_data/seq-01/frame-000000.depth", 32, 24, 1.0f);
  expectInputError([&] { loadDataset(dir); },
                   {"records_depth.txt:2:", "frame-000000.depth (sensor 'kinect_depth') has 3072 bytes",
                    "the sensor is 64x48 (12288 bytes of float32)"});
}

// kapture's timestamps are unsigned integers, compared as numbers: compared as text, the depth
// record "0000" missed the image "0" (as the format's own examples write them, padded), and text
// or negative timestamps passed.
TEST(Kapture, TimestampsAreUnsignedIntegers) {
  const fs::path dir = kaptureSample();
  const fs::path mapping = dir / "mapping/sensors";
  writeTextFile(mapping / "records_depth.txt", std::string(kKaptureHeader) + "0000, kinect_depth, seq-01/frame-000000.depth\n");
  const Scene scene = loadDataset(dir);
  EXPECT_TRUE(frameNamed(scene, "mapping/sensors/records_data/seq-01/frame-000000.color.jpg").depth.has_value());

  for (const std::string timestamp : {"t0", "0.5", "99999999999999999999"}) {
    writeTextFile(mapping / "records_camera.txt",
                  std::string(kKaptureHeader) + timestamp + ", kinect_rgb, seq-01/frame-000000.color.jpg\n");
    expectInputError([&] { loadDataset(dir); },
                     {"records_camera.txt:2:", "expected an integer for timestamp, got '" + timestamp + "'"});
  }
  writeTextFile(mapping / "records_camera.txt", std::string(kKaptureHeader) + "-1, kinect_rgb, seq-01/frame-000000.color.jpg\n");
  expectInputError([&] { loadDataset(dir); }, {"records_camera.txt:2:", "timestamp -1 is negative"});
  writeTextFile(mapping / "records_camera.txt", std::string(kKaptureHeader) + "0, kinect_rgb, seq-01/frame-000000.color.jpg\n");
  writeTextFile(mapping / "records_depth.txt", std::string(kKaptureHeader) + "-3, kinect_depth, seq-01/frame-000000.depth\n");
  expectInputError([&] { loadDataset(dir); }, {"records_depth.txt:2:", "timestamp -3 is negative"});
  writeTextFile(mapping / "records_depth.txt", std::string(kKaptureHeader) + "0, kinect_depth, seq-01/frame-000000.depth\n");
  writeTextFile(mapping / "trajectories.txt", std::string(kKaptureHeader) + "zero, kinect_rgb, 1, 0, 0, 0, 0, 0, 0\n");
  expectInputError([&] { loadDataset(dir); }, {"trajectories.txt:2:", "expected an integer for timestamp, got 'zero'"});
}

// Two records of one camera at one instant both took that instant's pose, so one image was scored
// against the other's; of two depth maps of one instant, the second was dropped.
TEST(Kapture, ASecondRecordOfOneInstantIsRefused) {
  const fs::path dir = kaptureSample();
  const fs::path mapping = dir / "mapping/sensors";
  writeImage(mapping / "records_data/seq-01/frame-000001.color.jpg", 64, 48);
  writeTextFile(mapping / "records_camera.txt", std::string(kKaptureHeader) +
                                                    "0, kinect_rgb, seq-01/frame-000000.color.jpg\n"
                                                    "0, kinect_rgb, seq-01/frame-000001.color.jpg\n");
  expectInputError([&] { loadDataset(dir); },
                   {"records_camera.txt:3:", "a second record for timestamp 0, device 'kinect_rgb' (first on line 2)"});
  writeTextFile(mapping / "records_camera.txt", std::string(kKaptureHeader) + "0, kinect_rgb, seq-01/frame-000000.color.jpg\n");
  writeTextFile(mapping / "records_depth.txt", std::string(kKaptureHeader) +
                                                   "0, kinect_depth, seq-01/frame-000000.depth\n"
                                                   "0, kinect_depth, seq-01/frame-000001.depth\n");
  expectInputError([&] { loadDataset(dir); },
                   {"records_depth.txt:3:", "a second record for timestamp 0, device 'kinect_depth' (first on line 2)"});
}

// The version line was a comment like any other: a later format, whose columns may differ, was
// read as 1.1. 1.0's sensors files differ from 1.1's only in that line.
TEST(Kapture, OnlyVersionsWhoseSensorFilesReadAlikeAreRead) {
  const fs::path dir = kaptureSample();
  const fs::path query = dir / "query/sensors";
  const std::string sensor = "phone, , camera, SIMPLE_RADIAL, 64, 48, 120, 30.5, 22.5, 0.01\n";
  writeTextFile(query / "sensors.txt", "# kapture format: 2.0\n" + sensor);
  expectInputError([&] { loadDataset(dir); }, {"sensors.txt:1:", "kapture format '2.0' is not one ffloc reads (1.0, 1.1)"});
  writeTextFile(query / "records_camera.txt", "# kapture format: 1.2\n7, phone, query/0007.jpg\n");
  writeTextFile(query / "sensors.txt", "# kapture format: 1.0\n" + sensor);
  expectInputError([&] { loadDataset(dir); }, {"records_camera.txt:1:", "kapture format '1.2'"});
  writeTextFile(query / "records_camera.txt", "7, phone, query/0007.jpg\n");
  EXPECT_EQ(loadDataset(dir).frames.size(), 2u);
}

// The version is found as kapture finds it, searching the first line for digits.digits: an exact
// string refused '# kapture format: 1.1 (note)' and read '#kapture format: 2.0' as 1.1.
TEST(Kapture, TheVersionIsFoundAsKaptureFindsIt) {
  const fs::path dir = kaptureSample();
  const fs::path query = dir / "query/sensors";
  const std::string sensor = "phone, , camera, SIMPLE_RADIAL, 64, 48, 120, 30.5, 22.5, 0.01\n";
  for (const std::string header : {"# kapture format: 1.1 (note)", "# kapture format:1.0", "#  kapture format : 1.1"}) {
    writeTextFile(query / "sensors.txt", header + "\n" + sensor);
    EXPECT_EQ(loadDataset(dir).frames.size(), 2u) << header;
  }
  for (const auto& [header, version] : {std::pair{"#kapture format: 2.0", "2.0"}, {"# kapture format: 1.10", "1.10"}}) {
    writeTextFile(query / "sensors.txt", std::string(header) + "\n" + sensor);
    expectInputError([&] { loadDataset(dir); }, {"sensors.txt:1:", "kapture format '" + std::string(version) + "'"});
  }
}

TEST(Kapture, DistortionBeyondAnyLensIsRefused) {
  const fs::path dir = kaptureSample();
  writeTextFile(dir / "query/sensors/sensors.txt",
                std::string(kKaptureHeader) + "phone, , camera, SIMPLE_RADIAL, 64, 48, 120, 30.5, 22.5, 1e10\n");
  expectInputError([&] { loadDataset(dir); }, {"sensors.txt:2:", "k1 1e+10: moves the image corner"});
  // A narrow lens's huge high-order terms move its pixels little (a 60 mm macro lens, scaled).
  writeTextFile(dir / "query/sensors/sensors.txt",
                std::string(kKaptureHeader) +
                    "phone, , camera, FULL_OPENCV, 64, 48, 800, 800, 32, 24, 0, -500, 0, 0, 300, 0, 0, 0\n");
  const Scene scene = loadDataset(dir);
  ASSERT_FALSE(scene.queryIndices().empty());
  for (const size_t i : scene.queryIndices())
    EXPECT_EQ(scene.frames[i].intrinsics.distortion, (std::vector<double>{0, -500, 0, 0, 300, 0, 0, 0}));
}

}  // namespace
}  // namespace ffloc
