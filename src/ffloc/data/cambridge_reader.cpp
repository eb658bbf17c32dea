#include <algorithm>
#include <cstdlib>
#include <map>
#include <numeric>

#include "ffloc/core/error.h"
#include "ffloc/core/utf8.h"
#include "ffloc/data/format_io.h"
#include "ffloc/io/image_size.h"
#include "ffloc/data/readers.h"
#include "ffloc/data/text_file.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

constexpr const char* kTrainFile = "dataset_train.txt";
constexpr const char* kTestFile = "dataset_test.txt";
constexpr const char* kReconstructionFile = "reconstruction.nvm";
// Focal lengths in the Cambridge reconstructions refer to the 1920x1080 frames; without the
// .nvm we fall back to a typical value of those reconstructions.
constexpr double kReferenceWidth = 1920.0;
constexpr double kDefaultFocal = 1670.0;

std::string withoutExtension(const std::string& name) {
  return fs::path(name).replace_extension().generic_string();
}

// Per-image focal lengths from the VisualSfM reconstruction shipped with each scene:
// "NVM_V3", then the camera count, then "<file> <focal> <qw qx qy qz> <centre> <radial> 0".
// Keyed by file name without extension (the .nvm names .jpg files, the split files .png).
std::map<std::string, double> readNvmFocals(const fs::path& file) {
  const auto lines = contentLines(readTextLines(file), false);
  if (lines.empty() || lines[0].text.find("NVM_V3") == std::string::npos)
    throwInputError(file.string(), 1, "expected an NVM_V3 header");
  const size_t i = 1;
  if (i >= lines.size()) throwInputError(file.string(), lines.back().number, "missing camera count");
  const long count = parseInteger(splitWhitespace(lines[i].text).front(), file, lines[i].number, "camera count");
  if (count < 0 || i + static_cast<size_t>(count) >= lines.size())
    throwInputError(file.string(), lines[i].number, "camera count " + std::to_string(count) + " exceeds the file");
  std::map<std::string, double> focals;
  for (long k = 0; k < count; ++k) {
    const TextLine& line = lines[i + 1 + k];
    const auto tokens = splitWhitespace(line.text);
    if (tokens.size() < 2) throwInputError(file.string(), line.number, "expected '<file> <focal> ...'");
    const double focal = parseDouble(tokens[1], file, line.number, "focal length");
    if (!(focal > 0) || !std::isfinite(focal)) throwInputError(file.string(), line.number, "focal length must be positive");
    focals[withoutExtension(tokens[0])] = focal;
  }
  return focals;
}

void readPoseList(const fs::path& file, const fs::path& dir, Split split, const std::map<std::string, double>& focals,
                  double fallback_focal, Scene& scene) {
  const auto lines = readTextLines(file);
  // Up to three header lines (title, column names, blank) before the first entry: three were
  // skipped whatever they held, so a list without its header lost its first three frames
  // without a word (found by an outside probe).
  const auto isEntry = [](const std::string& text) {
    const auto tokens = splitWhitespace(text);
    if (tokens.size() != 8) return false;
    for (size_t k = 1; k < tokens.size(); ++k) {
      char* end = nullptr;
      std::strtod(tokens[k].c_str(), &end);
      if (end == tokens[k].c_str() || *end != '\0') return false;
    }
    return true;
  };
  // A line naming an image (an existing file, or a first word that ends as an image name before
  // any comma) is an entry, read (and refused) as one when it is malformed.
  const auto namesAnImage = [&](const std::string& text) {
    const auto tokens = splitWhitespace(text);
    if (tokens.empty()) return false;
    const std::string first = asciiLowercase(tokens[0].substr(0, tokens[0].find(',')));
    return endsWith(first, ".png") || endsWith(first, ".jpg") || endsWith(first, ".jpeg") ||
           fs::is_regular_file(dir / tokens[0]);
  };
  size_t first = 0;
  while (first < std::min<size_t>(3, lines.size()) && !isEntry(lines[first].text) &&
         !namesAnImage(lines[first].text))
    ++first;
  for (size_t i = first; i < lines.size(); ++i) {
    const TextLine& line = lines[i];
    const auto tokens = splitWhitespace(line.text);
    if (tokens.empty()) continue;
    if (tokens.size() != 8) throwInputError(file.string(), line.number, "expected 'ImageFile X Y Z W P Q R'");
    double v[7];
    const char* names[] = {"X", "Y", "Z", "W", "P", "Q", "R"};
    for (int k = 0; k < 7; ++k) v[k] = parseDouble(tokens[1 + k], file, line.number, names[k]);
    const Eigen::Vector3d centre(v[0], v[1], v[2]);
    const double q_norm = Eigen::Vector4d(v[3], v[4], v[5], v[6]).norm();
    if (!centre.allFinite() || !std::isfinite(q_norm) || std::abs(q_norm - 1.0) > 1e-2)
      throwInputError(file.string(), line.number, "invalid pose (finite centre and unit quaternion required)");

    Frame frame;
    frame.image_path = dir / tokens[0];
    if (!fs::exists(frame.image_path))
      throwInputError(file.string(), line.number, "image " + frame.image_path.string() + " not found");
    frame.name = frameName(frame.image_path, dir);
    // WPQR is the world-to-camera rotation (as in VisualSfM's .nvm), XYZ the camera centre.
    frame.camera_to_world.R = Eigen::Quaterniond(v[3], v[4], v[5], v[6]).normalized().toRotationMatrix().transpose();
    frame.camera_to_world.t = centre;

    const cv::Size size = readImageSize(frame.image_path);
    const auto focal = focals.find(withoutExtension(tokens[0]));
    const double f = (focal != focals.end() ? focal->second : fallback_focal) * size.width / kReferenceWidth;
    Intrinsics& K = frame.intrinsics;
    K.width = size.width;
    K.height = size.height;
    K.fx = K.fy = f;
    K.cx = 0.5 * (size.width - 1);
    K.cy = 0.5 * (size.height - 1);
    frame.split = split;
    scene.frames.push_back(std::move(frame));
  }
}

}  // namespace

bool looksLikeCambridge(const fs::path& dir) {
  return fs::is_regular_file(dir / kTrainFile) || fs::is_regular_file(dir / kTestFile);
}

Scene readCambridge(const fs::path& dir) {
  Scene scene = emptyScene(dir, "cambridge", true);
  std::map<std::string, double> focals;
  double fallback_focal = kDefaultFocal;
  if (fs::exists(dir / kReconstructionFile)) {
    focals = readNvmFocals(dir / kReconstructionFile);
    if (!focals.empty())
      fallback_focal = std::accumulate(focals.begin(), focals.end(), 0.0,
                                       [](double sum, const auto& entry) { return sum + entry.second; }) /
                       focals.size();
  }
  bool any = false;
  for (const auto& [file_name, split] : {std::pair{kTrainFile, Split::kMapping}, {kTestFile, Split::kQuery}}) {
    if (!fs::exists(dir / file_name)) continue;
    readPoseList(dir / file_name, dir, split, focals, fallback_focal, scene);
    any = true;
  }
  if (!any) throwInputError(dir.string(), 0, "no dataset_train.txt or dataset_test.txt");
  return scene;
}

}  // namespace ffloc
