// Indoor6 (Do et al., CVPR 2022, "Learning to Detect Scene Landmarks for Camera Localization"),
// as its authors' loader reads it (microsoft/SceneLandmarkLocalization, src/dataloader/indoor6.py):
// one folder per scene with images/*.color.jpg and, beside each image, .pose.txt (3x4
// world-to-camera [R|t]) and .intrinsics.txt ("W H f cx cy ...", the COLMAP-derived camera); the
// splits are the lists of image names in train_test_val.pkl, a Python pickle.
#include <algorithm>
#include <cstdio>
#include <map>

#include "ffloc/core/error.h"
#include "ffloc/data/dataset_writers.h"
#include "ffloc/data/format_io.h"
#include "ffloc/data/pose_check.h"
#include "ffloc/data/readers.h"
#include "ffloc/data/text_file.h"
#include "ffloc/io/mapped_file.h"
#include "ffloc/io/pickle.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

constexpr const char* kColourSuffix = ".color.jpg";
constexpr const char* kPoseSuffix = ".pose.txt";
constexpr const char* kIntrinsicsSuffix = ".intrinsics.txt";
constexpr const char* kSplitFile = "train_test_val.pkl";
// The pickle's name lists; its train_idx, val_idx, test_idx repeat them as indices into the
// sorted images (numpy arrays in the authors' files) and are not read.
const std::pair<const char*, Split> kSplitKeys[] = {
    {"train", Split::kMapping}, {"test", Split::kQuery}, {"val", Split::kUnassigned}};
// A third-party converter's form of the same lists, read only when there is no pickle.
const std::pair<const char*, Split> kSplitLists[] = {
    {"_train.txt", Split::kMapping}, {"_test.txt", Split::kQuery}, {"_val.txt", Split::kUnassigned}};

// The authors' loader reads tokens 0-4 and, elsewhere, token 6 (the original COLMAP image name);
// token 5 is never read nor described, so it is not taken for a distortion coefficient.
// The cameras come from COLMAP, whose top-left pixel centre is (0.5, 0.5).
Intrinsics readIntrinsics(const fs::path& file) {
  const auto lines = contentLines(readTextLines(file), true);
  if (lines.size() != 1) throwInputError(file.string(), 0, "expected one line 'W H f cx cy ...'");
  const auto tokens = splitWhitespace(lines[0].text);
  if (tokens.size() < 5)
    throwInputError(file.string(), lines[0].number,
                    "expected 'W H f cx cy ...', found " + std::to_string(tokens.size()) + " values");
  const char* fields[] = {"W", "H", "f", "cx", "cy"};
  double values[5];
  for (int i = 0; i < 5; ++i) values[i] = parseDouble(tokens[i], file, lines[0].number, fields[i]);
  Intrinsics K;
  K.width = static_cast<int>(values[0]);
  K.height = static_cast<int>(values[1]);
  K.fx = K.fy = values[2];
  K.cx = values[3] - 0.5;
  K.cy = values[4] - 0.5;
  if (!K.isValid() || K.width != values[0] || K.height != values[1])
    throwInputError(file.string(), lines[0].number, "invalid camera (integer size and positive focal length needed)");
  return K;
}

Pose readWorldToCameraPose(const fs::path& file) {
  const MatrixFile matrix = readMatrixFile(file, 3, 4);
  Eigen::Matrix4d world_to_camera = Eigen::Matrix4d::Identity();
  world_to_camera.topRows<3>() = matrix.values;
  return validatedPose(world_to_camera, file, matrix.row_lines).inverse();
}

// One image name of a split list, with where it was read for messages.
struct SplitEntry {
  std::string image;
  Split split;
  fs::path file;
  int line = 0;     // in a text list
  std::string key;  // in the pickle
};

std::vector<SplitEntry> readSplitPickle(const fs::path& file) {
  const MappedFile bytes(file);
  const pickle::Unpickled splits = pickle::unpickle(bytes.data(), bytes.size(), file.string());
  if (splits.root->kind != pickle::Kind::kDict)
    throwInputError(file.string(), 0, "expected a dict with keys 'train', 'val', 'test'");
  std::vector<SplitEntry> entries;
  for (const auto& [key, split] : kSplitKeys) {
    const pickle::Value* names = pickle::dictGet(splits.root, key);
    // Nothing is taken from 'val' (its images stay unassigned), so a file without it still reads.
    if (!names && split == Split::kUnassigned) continue;
    if (!names) throwInputError(file.string(), 0, std::string("key '") + key + "' is missing");
    const bool strings = names->kind == pickle::Kind::kList &&
                         std::all_of(names->items.begin(), names->items.end(),
                                     [](const pickle::Value* name) { return name->kind == pickle::Kind::kString; });
    if (!strings) throwInputError(file.string(), 0, std::string("key '") + key + "' is not a list of strings");
    for (const pickle::Value* name : names->items) entries.push_back({name->text, split, file, 0, key});
  }
  return entries;
}

std::vector<SplitEntry> readSplitLists(const fs::path& dir) {
  std::vector<std::pair<fs::path, Split>> lists;
  for (const auto& entry : fs::directory_iterator(dir))
    for (const auto& [suffix, split] : kSplitLists)
      if (entry.is_regular_file() && endsWith(entry.path().filename().string(), suffix))
        lists.emplace_back(entry.path(), split);
  std::sort(lists.begin(), lists.end());
  std::vector<SplitEntry> entries;
  for (const auto& [list, split] : lists) {
    for (const auto& line : contentLines(readTextLines(list), true)) {
      const auto tokens = splitWhitespace(line.text);
      if (tokens.size() != 1)
        throwInputError(list.string(), line.number, "expected one image name, found '" + line.text + "'");
      entries.push_back({tokens[0], split, list, line.number, ""});
    }
  }
  return entries;
}

// Listed images take the list's split; 'val' images, like unlisted ones, stay unassigned (unless
// 'train' or 'test' lists them too: nothing says the authors' validation images are set apart).
void assignSplits(const std::vector<SplitEntry>& entries, const fs::path& images_dir, Scene* scene) {
  std::map<std::string, size_t> frame_of;  // image file name -> frame
  for (size_t i = 0; i < scene->frames.size(); ++i)
    frame_of[scene->frames[i].image_path.filename().string()] = i;
  for (const SplitEntry& entry : entries) {
    const std::string where = entry.key.empty() ? "" : "key '" + entry.key + "': ";
    const auto frame = frame_of.find(fs::path(entry.image).filename().string());
    if (frame == frame_of.end())
      throwInputError(entry.file.string(), entry.line,
                      where + "'" + entry.image + "' is not an image in " + images_dir.string());
    if (entry.split == Split::kUnassigned) continue;
    Split& split = scene->frames[frame->second].split;
    if (split != Split::kUnassigned && split != entry.split)
      throwInputError(entry.file.string(), entry.line,
                      where + "'" + entry.image + "' is in both the train and the test split");
    split = entry.split;
  }
}

}  // namespace

bool looksLikeIndoor6(const fs::path& dir) {
  if (!fs::is_directory(dir / "images")) return false;
  for (const auto& entry : fs::directory_iterator(dir / "images"))
    if (endsWith(entry.path().filename().string(), kIntrinsicsSuffix)) return true;
  return false;
}

Scene readIndoor6(const fs::path& dir) {
  Scene scene = emptyScene(dir, "indoor6", true);
  const fs::path images_dir = dir / "images";
  std::vector<fs::path> images;
  for (const auto& entry : fs::directory_iterator(images_dir))
    if (endsWith(entry.path().filename().string(), kColourSuffix)) images.push_back(entry.path());
  std::sort(images.begin(), images.end());
  for (const fs::path& image : images) {
    const std::string name = image.filename().string();
    const std::string stem = name.substr(0, name.size() - std::string(kColourSuffix).size());
    Frame frame;
    frame.image_path = image;
    frame.name = frameName(image, dir);
    const fs::path intrinsics_file = images_dir / (stem + kIntrinsicsSuffix);
    const fs::path pose_file = images_dir / (stem + kPoseSuffix);
    for (const fs::path& companion : {intrinsics_file, pose_file})
      if (!fs::exists(companion)) throwInputError(image.string(), 0, "no " + companion.filename().string() + " beside it");
    frame.intrinsics = readIntrinsics(intrinsics_file);
    requireImageSize(image, frame.intrinsics.width, frame.intrinsics.height, intrinsics_file.string(), 1);
    frame.camera_to_world = readWorldToCameraPose(pose_file);
    scene.frames.push_back(std::move(frame));
  }
  if (scene.frames.empty()) throwInputError(images_dir.string(), 0, std::string("no *") + kColourSuffix + " images");
  const fs::path split_file = dir / kSplitFile;
  assignSplits(fs::exists(split_file) ? readSplitPickle(split_file) : readSplitLists(dir), images_dir, &scene);
  return scene;
}

std::vector<std::string> writeIndoor6(const Scene& scene, const fs::path& out) {
  requireNoDistortion(scene, "indoor6");
  for (const Frame& frame : scene.frames)
    if (frame.intrinsics.fx != frame.intrinsics.fy)
      throwInputError(frame.name, 0, "has fx != fy, and Indoor6 stores one focal length");
  std::map<Split, std::vector<std::string>> split_images;
  std::map<Split, std::vector<int32_t>> split_indices;  // into the sorted images: the frames' order
  std::vector<std::string> names;
  for (size_t i = 0; i < scene.frames.size(); ++i) {
    const Frame& frame = scene.frames[i];
    char stem[32];
    std::snprintf(stem, sizeof(stem), "image-%06zu", i);
    const fs::path folder = out / "images";
    const std::string image = std::string(stem) + kColourSuffix;
    copyFrameImage(frame, folder / image, true);
    const Intrinsics& K = frame.intrinsics;
    writeTextCreatingFolders(folder / (std::string(stem) + kIntrinsicsSuffix),
                             std::to_string(K.width) + " " + std::to_string(K.height) + " " + formatNumber(K.fx) + " " +
                                 formatNumber(K.cx + 0.5) + " " + formatNumber(K.cy + 0.5) + "\n");
    const Eigen::Matrix4d world_to_camera = frame.camera_to_world.inverse().matrix();
    writeTextCreatingFolders(folder / (std::string(stem) + kPoseSuffix), matrixText(world_to_camera.topRows<3>()));
    split_images[frame.split].push_back(image);
    split_indices[frame.split].push_back(static_cast<int32_t>(i));
    names.push_back("images/" + image);
  }
  pickle::Writer splits;
  splits.op('}');  // EMPTY_DICT
  splits.op('(');  // MARK
  for (const auto& [key, split] : kSplitKeys) {
    splits.text(key);
    splits.stringList(split_images[split]);
    splits.text(std::string(key) + "_idx");
    splits.integerList(split_indices[split]);
  }
  splits.op('u');  // SETITEMS
  writeTextCreatingFolders(out / kSplitFile, splits.finish());
  return names;
}

}  // namespace ffloc
