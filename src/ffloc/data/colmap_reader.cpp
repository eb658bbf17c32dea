#include <algorithm>
#include <map>

#include "ffloc/core/error.h"
#include "ffloc/data/colmap_camera.h"
#include "ffloc/data/readers.h"
#include "ffloc/data/text_file.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

const char* const kModelFolders[] = {"", "sparse/0", "sparse", "reconstruction", "model"};

// OpenCV reads no image with a side beyond this (CV_IO_MAX_IMAGE_WIDTH).
constexpr long kMaxImageSide = 1 << 20;

long parseInteger(std::string_view token, const fs::path& file, int line, const std::string& field) {
  return ffloc::parseInteger(std::string(token), file, line, field);
}

double parseDouble(std::string_view token, const fs::path& file, int line, const std::string& field) {
  return ffloc::parseDouble(std::string(token), file, line, field);
}

// COLMAP's ids are unsigned; -1 appears only as a keypoint's POINT3D_ID, for a keypoint without a
// 3D point (`none_allowed`).
long colmapId(std::string_view token, const fs::path& file, int line, const std::string& field,
              bool none_allowed = false) {
  const long id = parseInteger(token, file, line, field);
  if (id < 0 && !(none_allowed && id == -1))
    throwInputError(file.string(), line,
                    field + " " + std::to_string(id) + " is negative (COLMAP ids are unsigned" +
                        (none_allowed ? "; -1 marks a keypoint without a 3D point)" : ")"));
  return id;
}

int imageSide(const std::string& token, const fs::path& file, int line, const std::string& field) {
  const long side = parseInteger(token, file, line, field);
  if (side < 1 || side > kMaxImageSide)
    throwInputError(file.string(), line,
                    field + " " + token + " is outside [1, " + std::to_string(kMaxImageSide) + "] pixels");
  return static_cast<int>(side);
}

std::optional<fs::path> findModelFolder(const fs::path& dir, const char* file_name) {
  for (const char* folder : kModelFolders)
    if (fs::is_regular_file(dir / folder / file_name)) return (dir / folder).lexically_normal();
  return std::nullopt;
}

std::map<long, Intrinsics> readCameras(const fs::path& file) {
  std::map<long, Intrinsics> cameras;
  for (const auto& line : contentLines(readTextLines(file), true)) {
    const auto tokens = splitWhitespace(line.text);
    if (tokens.size() < 4)
      throwInputError(file.string(), line.number, "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]");
    const long id = colmapId(tokens[0], file, line.number, "CAMERA_ID");
    const std::string& model = tokens[1];
    const auto parameter_count = colmapModelParameterCount(model);
    if (!parameter_count)
      throwInputError(file.string(), line.number,
                      "unsupported camera model '" + model + "' (supported: " + kSupportedColmapModels + ")");
    if (tokens.size() != 4 + *parameter_count)
      throwInputError(file.string(), line.number,
                      model + " takes " + std::to_string(*parameter_count) + " parameters, found " +
                          std::to_string(tokens.size() - 4));
    std::vector<double> parameters;
    for (size_t i = 4; i < tokens.size(); ++i)
      parameters.push_back(parseDouble(tokens[i], file, line.number, "parameter " + std::to_string(i - 3)));
    Intrinsics K = colmapIntrinsics(model, parameters);
    K.width = imageSide(tokens[2], file, line.number, "WIDTH");
    K.height = imageSide(tokens[3], file, line.number, "HEIGHT");
    requireLensDistortion(K, file, line.number);
    if (!K.isValid()) throwInputError(file.string(), line.number, "invalid camera (size and focal length must be positive)");
    if (!cameras.emplace(id, K).second)
      throwInputError(file.string(), line.number, "duplicate CAMERA_ID " + std::to_string(id));
  }
  return cameras;
}

bool isComment(const std::string& text) {
  const std::string_view content = trimmed(text);
  return !content.empty() && content.front() == '#';
}

// Keypoints of one image: far beyond any extractor's, and a bound on what a hostile line costs
// (a 28 MB POINTS2D line of 4 million short triples took 288 MB).
constexpr size_t kMaxPointsPerImage = 1'000'000;

struct ColmapImage {
  long id = 0;
  std::string name;
  int line = 0;
  Frame frame;
  std::vector<Eigen::Vector2d> points2d;  // COLMAP pixel convention, as stored
};

std::vector<ColmapImage> readImages(const fs::path& file, const std::map<long, Intrinsics>& cameras) {
  std::vector<ColmapImage> images;
  const auto lines = readTextLines(file);
  size_t i = 0;
  auto skipComments = [&] {
    while (i < lines.size() && isComment(lines[i].text)) ++i;
  };
  while (true) {
    // A pose line; blank lines between images are tolerated, but the POINTS2D line that follows
    // a pose line may itself be blank (an image without keypoints).
    skipComments();
    while (i < lines.size() && trimmed(lines[i].text).empty()) ++i;
    if (i >= lines.size()) break;
    const TextLine& pose_line = lines[i++];
    // Every line is read a token at a time: a hostile line may be megabytes long.
    TokenReader pose_tokens(pose_line.text);
    std::string_view tokens[10];
    if (pose_tokens.next(tokens, 10) < 10)
      throwInputError(file.string(), pose_line.number, "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME");
    ColmapImage image;
    image.line = pose_line.number;
    image.id = colmapId(tokens[0], file, pose_line.number, "IMAGE_ID");
    double q[4], t[3];
    const char* q_names[] = {"QW", "QX", "QY", "QZ"};
    const char* t_names[] = {"TX", "TY", "TZ"};
    for (int k = 0; k < 4; ++k) q[k] = parseDouble(tokens[1 + k], file, pose_line.number, q_names[k]);
    for (int k = 0; k < 3; ++k) t[k] = parseDouble(tokens[5 + k], file, pose_line.number, t_names[k]);
    const double q_norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!std::isfinite(q_norm) || std::abs(q_norm - 1.0) > 1e-2)
      throwInputError(file.string(), pose_line.number, "invalid pose (quaternion must be finite and unit length)");
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(t[k]))
        throwInputError(file.string(), pose_line.number, std::string("invalid pose: ") + t_names[k] + " is not finite");
    const long camera_id = colmapId(tokens[8], file, pose_line.number, "CAMERA_ID");
    const auto camera = cameras.find(camera_id);
    if (camera == cameras.end())
      throwInputError(file.string(), pose_line.number, "CAMERA_ID " + std::to_string(camera_id) + " is not in cameras.txt");
    image.name = tokens[9];
    for (std::string_view more; pose_tokens.next(&more);) (image.name += ' ') += more;
    image.frame.intrinsics = camera->second;
    // images.txt stores world-to-camera.
    image.frame.camera_to_world = Pose::fromQuaternion(q[0], q[1], q[2], q[3], Eigen::Vector3d(t[0], t[1], t[2])).inverse();

    skipComments();
    if (i < lines.size()) {
      const TextLine& points_line = lines[i++];
      // Straight into the points: the line may hold millions of them.
      TokenReader point_tokens(points_line.text);
      std::string_view x, y, point_id;
      while (point_tokens.next(&x)) {
        if (!point_tokens.next(&y) || !point_tokens.next(&point_id))
          throwInputError(file.string(), points_line.number, "POINTS2D must be triples X Y POINT3D_ID");
        if (image.points2d.size() == kMaxPointsPerImage)
          throwInputError(file.string(), points_line.number,
                          "more than " + std::to_string(kMaxPointsPerImage) + " POINTS2D for image '" + image.name +
                              "' (COLMAP's extractors keep tens of thousands)");
        colmapId(point_id, file, points_line.number, "POINT3D_ID", true);
        image.points2d.emplace_back(parseDouble(x, file, points_line.number, "X"),
                                    parseDouble(y, file, points_line.number, "Y"));
      }
    }
    images.push_back(std::move(image));
  }
  return images;
}

void readPoints(const fs::path& file, const std::map<long, size_t>& frame_of_image,
                const std::map<long, const ColmapImage*>& image_of_id, Scene& scene) {
  std::map<long, int> line_of_point;
  for (const auto& line : contentLines(readTextLines(file), true)) {
    const auto malformed = [&] {
      throwInputError(file.string(), line.number,
                      "expected POINT3D_ID X Y Z R G B ERROR TRACK[] (pairs IMAGE_ID POINT2D_IDX)");
    };
    TokenReader point_tokens(line.text);
    std::string_view tokens[8];
    if (point_tokens.next(tokens, 8) < 8) malformed();
    const long point_id = colmapId(tokens[0], file, line.number, "POINT3D_ID");
    if (const auto [first, inserted] = line_of_point.emplace(point_id, line.number); !inserted)
      throwInputError(file.string(), line.number,
                      "duplicate POINT3D_ID " + std::to_string(point_id) + " (first on line " +
                          std::to_string(first->second) + ")");
    ScenePoint point;
    const char* field_names[] = {"X", "Y", "Z", "R", "G", "B", "ERROR"};
    for (int k = 0; k < 7; ++k) {
      const double value = parseDouble(tokens[1 + k], file, line.number, field_names[k]);
      if (k < 3) point.position[k] = value;
    }
    if (!point.position.allFinite()) throwInputError(file.string(), line.number, "point position is not finite");
    for (std::string_view image_token, index_token; point_tokens.next(&image_token);) {
      if (!point_tokens.next(&index_token)) malformed();
      const long image_id = colmapId(image_token, file, line.number, "IMAGE_ID");
      const auto image = image_of_id.find(image_id);
      if (image == image_of_id.end())
        throwInputError(file.string(), line.number, "track names IMAGE_ID " + std::to_string(image_id) + ", not in images.txt");
      const long index = parseInteger(index_token, file, line.number, "POINT2D_IDX");
      if (index < 0 || static_cast<unsigned long>(index) >= image->second->points2d.size())
        throwInputError(file.string(), line.number,
                        "POINT2D_IDX " + std::to_string(index) + " out of range for image " + std::to_string(image_id));
      const Eigen::Vector2d colmap_pixel = image->second->points2d[static_cast<size_t>(index)];
      point.observations.push_back({frame_of_image.at(image_id), colmap_pixel - Eigen::Vector2d(0.5, 0.5)});
    }
    scene.points.push_back(std::move(point));
  }
}

}  // namespace

bool looksLikeColmap(const fs::path& dir) {
  return findModelFolder(dir, "images.txt").has_value() || findModelFolder(dir, "images.bin").has_value();
}

Scene readColmap(const fs::path& dir) {
  const auto model = findModelFolder(dir, "images.txt");
  if (!model) {
    if (const auto binary = findModelFolder(dir, "images.bin"))
      throwInputError((*binary / "images.bin").string(), 0,
                      "binary COLMAP models are not supported; convert with "
                      "'colmap model_converter --output_type TXT'");
    throwInputError(dir.string(), 0, "no COLMAP images.txt in it or in sparse/0, sparse, reconstruction, model");
  }
  Scene scene = emptyScene(dir, "colmap", false);
  const auto cameras = readCameras(*model / "cameras.txt");
  auto images = readImages(*model / "images.txt", cameras);
  std::sort(images.begin(), images.end(), [](const ColmapImage& a, const ColmapImage& b) { return a.name < b.name; });

  // The model folder without a trailing separator: "reconstruction/" (the dataset given as the
  // model folder itself) had itself as parent, so <model>/../images was never searched.
  fs::path model_folder = model->lexically_normal();
  if (!model_folder.has_filename()) model_folder = model_folder.parent_path();
  const std::vector<fs::path> image_folders = {dir / "images", model_folder / "images",
                                               model_folder.parent_path() / "images", model_folder, dir};
  std::optional<fs::path> image_folder;
  for (const auto& folder : image_folders) {
    if (!images.empty() && fs::is_regular_file(folder / images.front().name)) {
      image_folder = folder.lexically_normal();
      break;
    }
  }
  std::map<long, size_t> frame_of_image;
  std::map<long, const ColmapImage*> image_of_id;
  for (auto& image : images) {
    if (!image_folder || !fs::is_regular_file(*image_folder / image.name)) {
      std::string searched;
      for (const auto& folder : image_folders) searched += (searched.empty() ? "" : ", ") + folder.lexically_normal().string();
      throwInputError((*model / "images.txt").string(), image.line, "image '" + image.name + "' not found in " + searched);
    }
    if (!image_of_id.emplace(image.id, &image).second)
      throwInputError((*model / "images.txt").string(), image.line, "duplicate IMAGE_ID " + std::to_string(image.id));
    frame_of_image[image.id] = scene.frames.size();
    image.frame.image_path = *image_folder / image.name;
    image.frame.name = frameName(image.frame.image_path, dir);
    scene.frames.push_back(image.frame);
  }
  if (fs::exists(*model / "points3D.txt")) readPoints(*model / "points3D.txt", frame_of_image, image_of_id, scene);
  return scene;
}

}  // namespace ffloc
