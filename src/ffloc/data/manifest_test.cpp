#include "ffloc/data/manifest.h"

#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/data/dataset.h"
#include "ffloc/data/scene_test_util.h"

namespace ffloc {
namespace {

using testing::expectInputError;
using testing::writeTextFile;

// The reader checks every frame's image from its header.
void writeImage(const std::filesystem::path& path, int width, int height) {
  std::filesystem::create_directories(path.parent_path());
  cv::imwrite(path.string(), cv::Mat(height, width, CV_8UC3, cv::Scalar(40, 80, 120)));
}

Scene makeScene(const std::filesystem::path& root) {
  Scene scene;
  scene.name = "tiny";
  scene.root = root;
  scene.metric = false;
  Intrinsics a;
  a.width = 64;
  a.height = 48;
  a.fx = 50.123456789012345;
  a.fy = 51.0 / 3.0;
  a.cx = 31.5;
  a.cy = 23.5;
  Intrinsics b = a;
  b.distortion = {0.1, -0.01, 1e-4, -2e-4, 1.0 / 7.0};
  for (int i = 0; i < 4; ++i) {
    Frame frame;
    frame.name = "images/" + std::to_string(i) + ".png";
    frame.image_path = root / frame.name;
    writeImage(frame.image_path, 64, 48);
    frame.intrinsics = i == 3 ? b : a;
    frame.camera_to_world.R = Eigen::AngleAxisd(0.3 * i + 0.1, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    frame.camera_to_world.t = Eigen::Vector3d(M_PI * i, -1.0 / 3.0, 1e-12);
    if (i != 2) {
      DepthSource depth;
      depth.path = root / ("depth/" + std::to_string(i) + ".tiff");
      depth.scale = 1.0;
      depth.invalid_values = {};
      frame.depth = depth;
    }
    frame.split = i < 2 ? Split::kMapping : (i == 2 ? Split::kQuery : Split::kUnassigned);
    scene.frames.push_back(frame);
  }
  return scene;
}

TEST(Manifest, RoundTripsExactly) {
  const auto dir = testing::makeTempDir("ffloc-manifest");
  const Scene scene = makeScene(dir);
  writeManifest(scene, dir / kManifestFileName);
  EXPECT_TRUE(isManifestFile(dir / kManifestFileName));
  const Scene back = readManifest(dir / kManifestFileName);
  EXPECT_EQ(back.name, "tiny");
  EXPECT_EQ(back.format, "manifest");
  EXPECT_FALSE(back.metric);
  EXPECT_EQ(back.root, dir);
  ASSERT_EQ(back.frames.size(), scene.frames.size());
  for (size_t i = 0; i < scene.frames.size(); ++i) testing::expectSameFrame(back.frames[i], scene.frames[i]);
  // No stray temporary file is left beside it (the other entry is the images' folder).
  int files = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 2);
}

TEST(Manifest, SharesIdenticalCamerasAndWritesRelativePaths) {
  const auto dir = testing::makeTempDir("ffloc-manifest");
  writeManifest(makeScene(dir), dir / "sub" / kManifestFileName);
  std::ifstream in(dir / "sub" / kManifestFileName);
  const auto root = nlohmann::json::parse(in);
  EXPECT_EQ(root["cameras"].size(), 2u);
  EXPECT_EQ(root["frames"][0]["camera"], root["frames"][1]["camera"]);
  EXPECT_NE(root["frames"][0]["camera"], root["frames"][3]["camera"]);
  EXPECT_EQ(root["frames"][0]["image"], "../images/0.png");
  EXPECT_EQ(root["frames"][0]["depth"], "../depth/0.tiff");
  EXPECT_EQ(root["frames"][0]["name"], "images/0.png");  // differs from the relative path
  const Scene back = readManifest(dir / "sub" / kManifestFileName);
  EXPECT_EQ(back.frames[0].name, "images/0.png");
  EXPECT_EQ(back.frames[0].image_path, dir / "images/0.png");
}

// A manifest of one frame, a.png, of a 4 x 3 camera, with the pose given as JSON text.
std::string oneFrameManifest(const std::string& camera_to_world, const std::string& more_frame_fields = "") {
  return R"({"format": "ffloc-manifest", "version": 1,
    "cameras": {"cam": {"width": 4, "height": 3, "fx": 2, "fy": 2, "cx": 1.5, "cy": 1}},
    "frames": [{"image": "a.png", "camera": "cam", )" +
         more_frame_fields + R"("camera_to_world": )" + camera_to_world + "}]}";
}

TEST(Manifest, ReadsDefaults) {
  const auto dir = testing::makeTempDir("ffloc-manifest");
  writeTextFile(dir / "manifest.json",
                oneFrameManifest("[[1,0,0,1],[0,1,0,2],[0,0,1,3],[0,0,0,1]]", R"("depth": "a_depth.png", )"));
  writeImage(dir / "a.png", 4, 3);
  const Scene scene = readManifest(dir / "manifest.json");
  ASSERT_EQ(scene.frames.size(), 1u);
  const Frame& frame = scene.frames[0];
  EXPECT_EQ(frame.split, Split::kUnassigned);
  EXPECT_TRUE(scene.metric);
  ASSERT_TRUE(frame.depth.has_value());
  EXPECT_EQ(frame.depth->scale, 0.001);
  EXPECT_EQ(frame.depth->invalid_values, (std::vector<double>{0.0, 65535.0}));
  EXPECT_EQ(frame.depth->path, dir / "a_depth.png");
  EXPECT_EQ(frame.camera_to_world.t, Eigen::Vector3d(1, 2, 3));
  EXPECT_TRUE(frame.intrinsics.distortion.empty());
}

// A rotation whose text lost digits (here 1e-3 off orthonormal) was kept as written; a map built
// from it then refused to load ("not a rigid transform"). It is projected onto the nearest rotation
// now, while one that is a rotation as written is kept bit for bit (RoundTripsExactly).
TEST(Manifest, NearlyOrthonormalRotationsAreProjected) {
  const auto dir = testing::makeTempDir("ffloc-manifest");
  writeTextFile(dir / "manifest.json", oneFrameManifest("[[1,0.001,0,1],[0,1,0,2],[0,0,1,3],[0,0,0,1]]"));
  writeImage(dir / "a.png", 4, 3);
  const Pose pose = readManifest(dir / "manifest.json").frames.at(0).camera_to_world;
  EXPECT_LT(orthogonalityError(pose.R), 1e-12);
  EXPECT_NEAR(pose.R.determinant(), 1.0, 1e-12);
  EXPECT_NEAR(pose.R(0, 1), 0.0005, 1e-6);  // halfway, as the nearest rotation lies
  EXPECT_EQ(pose.t, Eigen::Vector3d(1, 2, 3));
}

struct BadManifest {
  std::string edit_from, edit_to, expected;
};

TEST(Manifest, RejectsBadFieldsNamingThem) {
  const std::string good = R"({"format": "ffloc-manifest", "version": 1, "name": "x", "metric": true,
    "cameras": {"0": {"width": 4, "height": 3, "fx": 2, "fy": 2, "cx": 1.5, "cy": 1}},
    "frames": [{"image": "a.png", "camera": "0", "split": "query",
                "camera_to_world": [[1,0,0,1],[0,1,0,2],[0,0,1,3],[0,0,0,1]]}]})";
  const std::vector<BadManifest> cases = {
      {"\"version\": 1", "\"version\": 7", "field 'version'"},
      {"\"format\": \"ffloc-manifest\"", "\"format\": \"other\"", "field 'format'"},
      {"\"camera\": \"0\"", "\"camera\": \"9\"", "frames[0].camera"},
      {"\"split\": \"query\"", "\"split\": \"train\"", "frames[0].split"},
      {"\"fx\": 2", "\"fx\": -2", "cameras.0"},
      {"\"width\": 4", "\"width\": 4.5", "cameras.0.width"},
      {"[0,0,0,1]]", "[0,0,1,1]]", "frames[0].camera_to_world"},
      {"[1,0,0,1],", "[1,0,0],", "frames[0].camera_to_world"},
      {"[1,0,0,1],", "[2,0,0,1],", "not orthonormal"},
      {"[1,0,0,1],", "[1,0,0,1e300],", "camera centre is 1e+300 from the origin"},
      {"\"image\": \"a.png\",", "", "frames[0].image"},
      // Mapped under an empty name, then not converted ("images/: cannot write").
      {"\"camera\": \"0\"", "\"name\": \"\", \"camera\": \"0\"", "field 'frames[0].name': empty"},
      {"\"metric\": true", "\"metric\": true,", "invalid JSON"},
      // Misspelt or invented fields were read as absent: "k1" gave no distortion, without a word.
      {"\"cy\": 1}", "\"cy\": 1, \"k1\": 0.1}", "field 'cameras.0.k1': unknown field (known here: width, height"},
      {"\"split\": \"query\"", "\"spilt\": \"query\"", "field 'frames[0].spilt': unknown field"},
      {"\"metric\": true", "\"metric\": true, \"units\": \"cm\"", "field 'units': unknown field"},
      // Read as a lens, without a word.
      {"\"cy\": 1}", "\"cy\": 1, \"distortion\": [1e10, 0, 0, 0]}",
       "field 'cameras.0.distortion': k1 1e+10: moves the image corner"},
  };
  const auto dir = testing::makeTempDir("ffloc-manifest");
  writeImage(dir / "a.png", 4, 3);
  ASSERT_NO_THROW(readManifest((writeTextFile(dir / "manifest.json", good), dir / "manifest.json")));
  for (const auto& bad : cases) {
    SCOPED_TRACE(bad.edit_to);
    std::string text = good;
    const size_t at = text.find(bad.edit_from);
    ASSERT_NE(at, std::string::npos);
    text.replace(at, bad.edit_from.size(), bad.edit_to);
    writeTextFile(dir / "manifest.json", text);
    expectInputError([&] { readManifest(dir / "manifest.json"); }, {"manifest.json", bad.expected});
  }
  expectInputError([&] { readManifest(dir / "missing.json"); }, {"missing.json", "not found"});
}

// Images were never looked at: `ffloc eval --methods oracle-depth` scored a query whose image
// was missing, or was not an image, 100 %.
TEST(Manifest, MissingBrokenOrMissizedImagesAreRefusedNamingTheFrame) {
  const auto dir = testing::makeTempDir("ffloc-manifest");
  writeTextFile(dir / "manifest.json", R"({"format": "ffloc-manifest", "version": 1,
    "cameras": {"0": {"width": 4, "height": 3, "fx": 2, "fy": 2, "cx": 1.5, "cy": 1}},
    "frames": [{"image": "a.png", "camera": "0", "split": "query",
                "camera_to_world": [[1,0,0,1],[0,1,0,2],[0,0,1,3],[0,0,0,1]]}]})");
  expectInputError([&] { readManifest(dir / "manifest.json"); }, {"manifest.json", "frames[0].image", "a.png", "not found"});
  writeTextFile(dir / "a.png", "not an image");
  expectInputError([&] { readManifest(dir / "manifest.json"); }, {"manifest.json", "frames[0].image", "a.png"});
  writeImage(dir / "a.png", 5, 3);
  expectInputError([&] { readManifest(dir / "manifest.json"); },
                   {"manifest.json", "frames[0].image", "a.png is 5x3, but camera '0' is 4x3"});
  writeImage(dir / "a.png", 4, 3);
  EXPECT_EQ(readManifest(dir / "manifest.json").frames.size(), 1u);
}

// A mapping frame with intrinsics a query would be refused gave a map that refused every query.
TEST(Manifest, EveryFrameGetsTheChecksOfAQuery) {
  const auto dir = testing::makeTempDir("ffloc-manifest");
  writeImage(dir / "a.png", 4, 3);
  const std::string good = R"({"format": "ffloc-manifest", "version": 1,
    "cameras": {"0": {"width": 4, "height": 3, "fx": 2, "fy": 2, "cx": 1.5, "cy": 1}},
    "frames": [{"image": "a.png", "camera": "0", "split": "mapping",
                "camera_to_world": [[1,0,0,1],[0,1,0,2],[0,0,1,3],[0,0,0,1]]}]})";
  writeTextFile(dir / "manifest.json", good);
  EXPECT_EQ(loadDataset(dir).frames.size(), 1u);
  std::string outside = good;
  outside.replace(outside.find("\"cx\": 1.5"), 9, "\"cx\": 5000");
  writeTextFile(dir / "manifest.json", outside);
  expectInputError([&] { loadDataset(dir); }, {dir.string(), "frame 'a.png'", "cx, cy", "outside the 4x3 image"});
  std::string absurd = good;
  absurd.replace(absurd.find("\"fx\": 2"), 7, "\"fx\": 1e300");
  writeTextFile(dir / "manifest.json", absurd);
  expectInputError([&] { loadDataset(dir); }, {dir.string(), "frame 'a.png'", "fx: focal length"});
  // Too short as well as too long: 4e-320 px gave infinite errors, scored as an evaluation.
  std::string tiny = good;
  tiny.replace(tiny.find("\"fy\": 2"), 7, "\"fy\": 4e-320");
  writeTextFile(dir / "manifest.json", tiny);
  expectInputError([&] { loadDataset(dir); }, {dir.string(), "frame 'a.png'", "fy: focal length", "is not in [0.004, 4000]"});
}

// "./a.png" beside "a.png" gave one file two frames with two poses. Names stay as written:
// maps built before name their images so.
TEST(Manifest, OneImageFileSpeltTwoWaysIsRefused) {
  const auto dir = testing::makeTempDir("ffloc-manifest");
  writeImage(dir / "images" / "a.png", 4, 3);
  const std::string frame = R"({"image": "IMAGE", "camera": "0", "split": "mapping",
                               "camera_to_world": [[1,0,0,1],[0,1,0,2],[0,0,1,3],[0,0,0,1]]})";
  auto manifest = [&](const std::vector<std::string>& images) {
    std::string frames;
    for (const std::string& image : images) {
      std::string entry = frame;
      entry.replace(entry.find("IMAGE"), 5, image);
      frames += (frames.empty() ? "" : ",") + entry;
    }
    return R"({"format": "ffloc-manifest", "version": 1,
      "cameras": {"0": {"width": 4, "height": 3, "fx": 2, "fy": 2, "cx": 1.5, "cy": 1}}, "frames": [)" + frames + "]}";
  };
  writeTextFile(dir / "manifest.json", manifest({"./images/a.png"}));
  EXPECT_EQ(readManifest(dir / "manifest.json").frames.at(0).name, "./images/a.png");
  for (const std::string& other : {"./images/a.png", "images/./a.png", "images//a.png", "images/../images/a.png"}) {
    writeTextFile(dir / "manifest.json", manifest({"images/a.png", other}));
    expectInputError([&] { readManifest(dir / "manifest.json"); },
                     {"frames[1]", "'" + other + "' is the image of frame 'images/a.png' too"});
  }
}

TEST(Manifest, OverflowingNumberIsRejected) {
  // JSON has no NaN or inf literal; an out-of-range exponent is the nearest a file can get.
  const auto dir = testing::makeTempDir("ffloc-manifest");
  writeTextFile(dir / "manifest.json", oneFrameManifest("[[1,0,0,1e999],[0,1,0,2],[0,0,1,3],[0,0,0,1]]"));
  expectInputError([&] { readManifest(dir / "manifest.json"); }, {"manifest.json", "invalid JSON", "1e999"});
}

// Python's json.dump writes NaN, which JSON lacks: the folder was reported as "unknown dataset
// format". It is a manifest, and the error says what is wrong with it.
TEST(Manifest, PythonNaNIsReportedAsSuch) {
  const auto dir = testing::makeTempDir("ffloc-manifest");
  writeTextFile(dir / "manifest.json", R"({"format": "ffloc-manifest", "version": 1,
    "cameras": {"0": {"width": 4, "height": 3, "fx": NaN, "fy": 2, "cx": 1.5, "cy": 1}}, "frames": []})");
  expectInputError([&] { loadDataset(dir); },
                   {"manifest.json", "invalid JSON", "NaN and Infinity are not JSON"});
}

// An integer beyond int was narrowed: 4294967297 read as version 1.
TEST(Manifest, IntegersBeyondIntAreRefused) {
  const auto dir = testing::makeTempDir("ffloc-manifest");
  const std::string rest = R"(, "cameras": {"0": {"width": 4, "height": 3, "fx": 2, "fy": 2, "cx": 1.5, "cy": 1}},
    "frames": []})";
  writeTextFile(dir / "manifest.json", R"({"format": "ffloc-manifest", "version": 4294967297)" + rest);
  expectInputError([&] { readManifest(dir / "manifest.json"); }, {"manifest.json", "field 'version'", "expected an integer"});
  writeTextFile(dir / "manifest.json", R"({"format": "ffloc-manifest", "version": 1)" +
                                           std::string(R"(, "cameras": {"0": {"width": 4294967300, "height": 3, "fx": 2, "fy": 2, "cx": 1.5, "cy": 1}}, "frames": []})"));
  expectInputError([&] { readManifest(dir / "manifest.json"); }, {"manifest.json", "cameras.0.width"});
  // 640.0 was told "expected an integer in [...]", a range 640 lies in.
  writeTextFile(dir / "manifest.json", R"({"format": "ffloc-manifest", "version": 1)" +
                                           std::string(R"(, "cameras": {"0": {"width": 4.0, "height": 3, "fx": 2, "fy": 2, "cx": 1.5, "cy": 1}}, "frames": []})"));
  expectInputError([&] { readManifest(dir / "manifest.json"); },
                   {"manifest.json", "cameras.0.width", "(written 4.0: drop the decimal point)"});
}

}  // namespace
}  // namespace ffloc
