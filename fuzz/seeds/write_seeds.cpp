// Writes the seed corpora of fuzz/corpus/<target>/ (make fuzz-seeds). Every seed is written
// here, from our own writers (safetensors, map file, manifest, torch.save archives) or as the
// text a dataset's own tools write, on synthetic values: no file comes from elsewhere. Seeds are
// small on purpose; libFuzzer grows the corpus from them.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "../support/fuzz_support.h"
#include "ffloc/data/manifest.h"
#include "ffloc/io/map_file.h"
#include "ffloc/io/tensor_archive.h"
#include "ffloc/io/testing/torch_save_writer.h"

namespace {

namespace fs = std::filesystem;
using namespace ffloc;
using testing::PickleWriter;

fs::path corpus_root;

void writeSeed(const std::string& target, const std::string& name, const std::string& bytes) {
  const fs::path file = corpus_root / target / name;
  fs::create_directories(file.parent_path());
  std::ofstream(file, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

std::string readFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Dataset seeds hold one file per piece, joined by NUL (fuzz_support.h, splitFiles).
std::string joinFiles(const std::vector<std::string>& files) {
  std::string joined;
  for (size_t i = 0; i < files.size(); ++i) joined += (i ? std::string(1, '\0') : "") + files[i];
  return joined;
}

template <typename T>
std::string bytesOf(const std::vector<T>& values) {
  return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
}

Pose turnedPose(double angle, const Eigen::Vector3d& centre) {
  Pose pose;
  pose.R = Eigen::AngleAxisd(angle, Eigen::Vector3d(0.2, 1, 0.1).normalized()).toRotationMatrix();
  pose.t = centre;
  return pose;
}

std::string matrixLines(const Eigen::Matrix4d& T) {
  std::string text;
  char line[160];
  for (int r = 0; r < 4; ++r) {
    std::snprintf(line, sizeof(line), "%.9g\t%.9g\t%.9g\t%.9g\t\r\n", T(r, 0), T(r, 1), T(r, 2), T(r, 3));
    text += line;
  }
  return text;
}

void writeWeightSeeds(const fs::path& scratch) {
  const std::vector<float> floats = {0.5f, -1.f, 2.f, 3.5f, 0.f, 1e-3f};
  const std::vector<uint16_t> halves = {0x3c00, 0xc000};
  const std::vector<int64_t> longs = {7, -3};
  std::vector<TensorView> tensors(4);
  tensors[0] = {"encoder.weight", DType::kF32, {2, 3}, reinterpret_cast<const uint8_t*>(floats.data()), 24};
  tensors[1] = {"encoder.scale", DType::kF16, {2}, reinterpret_cast<const uint8_t*>(halves.data()), 4};
  tensors[2] = {"steps", DType::kI64, {2}, reinterpret_cast<const uint8_t*>(longs.data()), 16};
  tensors[3] = {"empty", DType::kF32, {0, 4}, nullptr, 0};
  writeSafetensors(scratch / "weights.safetensors", tensors, {{"format", "pt"}});
  writeSeed("safetensors", "four_tensors", readFile(scratch / "weights.safetensors"));
  writeSafetensors(scratch / "one.safetensors", {tensors[1]});
  writeSeed("safetensors", "one_tensor", readFile(scratch / "one.safetensors"));

  // A plain state dict: storage offsets, a transposed view, an alias, a half tensor and a
  // non-tensor entry; storage "0" holds 16 floats and "1" 16 bytes, as the checkpoint target's.
  PickleWriter plain;
  plain.global("collections", "OrderedDict");
  plain.op(')');
  plain.op('R');
  plain.op('(');
  plain.text("a");
  plain.tensor("FloatStorage", "0", 16, 2, {2, 3}, {3, 1});
  plain.text("b.t");
  plain.tensor("FloatStorage", "0", 16, 0, {3, 2}, {1, 3});
  plain.text("h");
  plain.tensor("HalfStorage", "1", 8, 0, {2, 2}, {2, 1});
  plain.text("alias");
  plain.tensor("FloatStorage", "0", 16, 2, {2, 3}, {3, 1});
  plain.text("epoch");
  plain.integer(7);
  plain.op('u');
  // DUSt3R's layout: {"model": state dict, "args": an opaque object}.
  PickleWriter wrapped;
  wrapped.op('}');
  wrapped.op('(');
  wrapped.text("args");
  wrapped.global("argparse", "Namespace");
  wrapped.op(')');
  wrapped.op('\x81');
  wrapped.text("model");
  wrapped.global("collections", "OrderedDict");
  wrapped.op(')');
  wrapped.op('R');
  wrapped.text("w");
  wrapped.global("torch._utils", "_rebuild_parameter");
  wrapped.op('(');
  wrapped.tensor("ByteStorage", "1", 16, 4, {3, 4}, {4, 1});
  wrapped.op('\x88');
  wrapped.global("collections", "OrderedDict");
  wrapped.op(')');
  wrapped.op('R');
  wrapped.op('t');
  wrapped.op('R');
  wrapped.op('s');
  wrapped.op('u');
  for (const auto& [name, pickle] : {std::pair{"plain_state_dict", plain.finish()}, {"model_and_args", wrapped.finish()}}) {
    writeSeed("pickle", name, pickle);
    writeSeed("pytorch_checkpoint", name, pickle);
  }
  const std::vector<testing::ZipMember> members = {{"archive/data.pkl", plain.finish()},
                                                   {"archive/byteorder", "little"},
                                                   {"archive/data/0", std::string(64, '\1')},
                                                   {"archive/data/1", std::string(16, '\2')}};
  writeSeed("zip", "checkpoint", testing::makeZip(members, false));
  writeSeed("zip", "checkpoint_zip64", testing::makeZip(members, true));
  writeSeed("safetensors", "checkpoint.pth", testing::makeZip(members, false));
}

MapFile smallMap(bool with_vlad) {
  MapFile map;
  map.model_id = "fuzz-seed";
  map.token_dim = 4;
  for (int i = 0; i < 2; ++i) {
    MapImage image;
    image.name = "frame-" + std::to_string(i) + ".png";
    image.camera_to_world = turnedPose(0.2 * i, {0.1 * i, 0.0, -0.2});
    image.intrinsics = {40.5, 41.0, 15.5, 11.5, 32, 24, {}};
    image.geometry = {64, 48, 32, 24, 0, 0, 32, 24};
    image.grid_rows = 2;
    image.grid_cols = 2;
    std::vector<uint16_t> tokens;
    for (int t = 0; t < 2 * 2 * 4; ++t) tokens.push_back(static_cast<uint16_t>(0x3800 + 16 * t + i));
    image.tokens = StoredTokens(std::move(tokens));
    image.descriptor = {0.5f, -0.5f, 0.5f * i, 0.25f};
    if (with_vlad) image.vlad_descriptor.assign(128, 0.01f * (i + 1));
    map.images.push_back(image);
  }
  if (with_vlad) map.vlad_centres.assign(128, 0.5f);
  return map;
}

void writeMapSeeds(const fs::path& scratch) {
  for (const bool with_vlad : {false, true}) {
    const fs::path path = scratch / "map.safetensors";
    writeMapFile(smallMap(with_vlad), path);
    writeSeed("map_file", with_vlad ? "two_images_vlad" : "two_images", readFile(path));
  }
}

void writeManifestSeeds(const fs::path& scratch) {
  Scene scene;
  scene.name = "seed";
  for (int i = 0; i < 2; ++i) {
    Frame frame;
    frame.name = i == 0 ? "images/a.png" : "images/b.png";
    frame.image_path = scratch / frame.name;
    frame.intrinsics = {9.5, 9.0, 3.5, 2.5, fuzz::kImageWidth, fuzz::kImageHeight, {}};
    if (i == 1) frame.intrinsics.distortion = {0.01, -0.002, 0.0, 0.001};
    frame.camera_to_world = turnedPose(0.3 * i, {0.0, 0.1 * i, 0.0});
    frame.split = i == 0 ? Split::kMapping : Split::kQuery;
    if (i == 0) {
      DepthSource depth;
      depth.path = scratch / "depth/a.png";
      depth.camera = Intrinsics{9.0, 9.0, 3.5, 2.5, fuzz::kImageWidth, fuzz::kImageHeight, {}};
      frame.depth = depth;
    }
    scene.frames.push_back(frame);
  }
  writeManifest(scene, scratch / "manifest.json");
  const std::string manifest = readFile(scratch / "manifest.json");
  writeSeed("manifest", "two_frames", manifest);
  writeSeed("manifest", "two_frames_resplit", joinFiles({manifest, "images/b.png\n", "# query\n./images/a.png\n"}));
}

void writeSevenScenesSeeds() {
  const std::string train = "sequence1\n", test = "sequence2\r\n";
  const std::string intrinsics = "585 0 320\n0 585 240\n0 0 1\n";
  const std::vector<std::string> poses = {matrixLines(turnedPose(0.0, {0, 0, 0}).matrix()),
                                          matrixLines(turnedPose(0.1, {0.05, 0, 0.01}).matrix()),
                                          matrixLines(turnedPose(-0.2, {0, 0.1, 0.3}).matrix())};
  writeSeed("seven_scenes", "two_sequences", joinFiles({poses[0], poses[1], poses[2], train, test}));
  writeSeed("seven_scenes", "intrinsics_and_split",
            joinFiles({poses[0], poses[1], poses[2], train, test, "9.5 0 4\n0 9.5 3\n0 0 1\n",
                       "seq-01/frame-000001.color.png\n"}));
  writeSeed("seven_scenes", "depth_camera", joinFiles({poses[0], poses[1], poses[2], train, test, intrinsics}));
}

void writeColmapSeeds() {
  const std::string cameras =
      "# Camera list with one line of data per camera:\n"
      "1 PINHOLE 8 6 9.5 9.25 4 3\n"
      "2 OPENCV 8 6 9 9 4 3 0.01 -0.001 0.0005 0.0002\n"
      "3 SIMPLE_RADIAL 8 6 9 4 3 0.02\n";
  const std::string images =
      "# Image list with two lines of data per image:\n"
      "1 1 0 0 0 0.1 0.2 0.3 1 a.png\n"
      "4 3 5 2 6 3\n"
      "2 0.99500416527802582 0 0.099833416646828155 0 -0.1 0 0.2 2 b.png\n"
      "1.5 2.5 1 7 1 -1\n"
      "3 0.98006657784124163 0.19866933079506122 0 0 0 0 1 3 c.png\n"
      "\n";
  const std::string points =
      "# 3D point list with one line of data per point:\n"
      "1 0.5 0.25 4 255 128 0 0.5 1 1 2 0\n"
      "2 -0.5 0.1 3.5 10 20 30 1.2 1 0\n";
  writeSeed("colmap", "three_images", joinFiles({cameras, images, points}));
  writeSeed("colmap", "three_images_split", joinFiles({cameras, images, points, "images/b.png\n"}));
}

void writeStrechaSeeds() {
  auto cameraFile = [](double angle, double radial) {
    const Pose pose = turnedPose(angle, {1.0, 2.0, -0.5});
    char text[1024];
    std::snprintf(text, sizeof(text),
                  "9.5 0 4\n0 9.5 3\n0 0 1\n%g 0 0\n%.12g %.12g %.12g\n%.12g %.12g %.12g\n%.12g %.12g %.12g\n"
                  "%g %g %g\n%d %d\n",
                  radial, pose.R(0, 0), pose.R(0, 1), pose.R(0, 2), pose.R(1, 0), pose.R(1, 1), pose.R(1, 2),
                  pose.R(2, 0), pose.R(2, 1), pose.R(2, 2), pose.t.x(), pose.t.y(), pose.t.z(), fuzz::kImageWidth,
                  fuzz::kImageHeight);
    return std::string(text);
  };
  writeSeed("strecha", "two_cameras", joinFiles({cameraFile(0.1, 0.0), cameraFile(-0.3, 0.01)}));
}

void writeCambridgeSeeds() {
  const std::string header = "Visual Landmark Dataset V1\nImageFile, Camera Position [X Y Z W P Q R]\n\n";
  const std::string train = header +
                            "seq1/frame00001.png 1.5 -2.0 0.5 0.7071067811865476 0 0.7071067811865476 0\n"
                            "seq1/frame00002.png 1.6 -2.0 0.5 1 0 0 0\n";
  const std::string test = header + "seq1/frame00003.png 1.7 -2.1 0.5 0.9950041652780258 0.0998334166468281 0 0\n";
  const std::string nvm = "NVM_V3\n\n2\nseq1/frame00001.jpg 1680.5 1 0 0 0 1.5 -2 0.5 0 0\n"
                          "seq1/frame00002.jpg 1675 1 0 0 0 1.6 -2 0.5 0 0\n\n0\n";
  writeSeed("cambridge", "train_test", joinFiles({train, test}));
  writeSeed("cambridge", "train_test_nvm", joinFiles({train, test, nvm}));
}

void writeNerfSeeds() {
  const std::string blender_train = R"({"camera_angle_x": 0.6911112070083618, "frames": [
  {"file_path": "./train/r_0", "rotation": 0.012, "transform_matrix": [[-1, 0, 0, 0], [0, -0.73, 0.68, 2.7], [0, 0.68, 0.73, 2.9], [0, 0, 0, 1]]},
  {"file_path": "./train/r_1.png", "transform_matrix": [[1, 0, 0, 0.1], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]}]})";
  const std::string blender_val = R"({"camera_angle_x": 0.69, "frames": []})";
  const std::string blender_test = R"({"camera_angle_x": 0.69, "camera_angle_y": 0.52, "frames": [
  {"file_path": "test/r_0", "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]}]})";
  const std::string nerfstudio = R"({"camera_model": "OPENCV", "fl_x": 9.5, "fl_y": 9.25, "cx": 4, "cy": 3, "w": 8, "h": 6,
  "k1": 0.01, "k2": -0.001, "p1": 0, "p2": 0.0002, "frames": [
  {"file_path": "train/r_0.png", "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]},
  {"file_path": "test/r_0.png", "fl_x": 10, "w": 8, "h": 6, "transform_matrix": [[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]}]})";
  writeSeed("nerf", "blender", joinFiles({blender_train, blender_val, blender_test}));
  writeSeed("nerf", "nerfstudio", joinFiles({"{}", "", "", nerfstudio}));
}

std::string encoded(const std::string& extension) {
  std::vector<uint8_t> bytes;
  cv::imencode(extension, cv::Mat(fuzz::kImageHeight, fuzz::kImageWidth, CV_8UC3, cv::Scalar(10, 200, 90)), bytes);
  return std::string(bytes.begin(), bytes.end());
}

void writeImageSeeds() {
  writeSeed("image_size", "small.png", fuzz::smallPng());
  const std::string jpeg = encoded(".jpg");
  writeSeed("image_size", "small.jpg", jpeg);
  // A JPEG whose first segment is an APP1 that is not EXIF, which the sniffer skips over.
  writeSeed("image_size", "app1.jpg", jpeg.substr(0, 2) + std::string("\xff\xe1\x00\x08XMP\0\0\0", 10) + jpeg.substr(2));
  const std::string fields = "fx=9.5\nfy=9.5\ncx=3.5\ncy=2.5\nname=query one\ntop_k=5\nfeatures=300\nseed=7\nselection=uniform";
  writeSeed("localize_request", "png", fields + std::string(1, '\0') + fuzz::smallPng());
  writeSeed("localize_request", "jpeg_distorted",
            "fx=9\nfy=9\ncx=4\ncy=3\ndistortion=0.01,-0.002,0,0.001,0" + std::string(1, '\0') + jpeg);
  // What once reached OpenCV's DICOM decoder and aborted the server (docs/fuzzing.md, findings).
  writeSeed("localize_request", "dicom_signature",
            "fx=9.5\nfy=9.5\ncx=3.5\ncy=2.5" + std::string(1, '\0') + std::string(128, '\n') + "DICM.5\n");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s CORPUS_FOLDER (fuzz/corpus)\n", argv[0]);
    return 2;
  }
  corpus_root = argv[1];
  const fs::path scratch = fuzz::scratchFolder().path();
  writeWeightSeeds(scratch);
  writeMapSeeds(scratch);
  writeManifestSeeds(scratch);
  writeSevenScenesSeeds();
  writeColmapSeeds();
  writeStrechaSeeds();
  writeCambridgeSeeds();
  writeNerfSeeds();
  writeImageSeeds();
  return 0;
}
