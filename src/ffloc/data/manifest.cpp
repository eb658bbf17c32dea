#include "ffloc/data/manifest.h"

#include <cmath>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "ffloc/core/error.h"
#include "ffloc/core/text_file_writer.h"
#include "ffloc/data/format_io.h"
#include "ffloc/geometry/camera.h"
#include "ffloc/io/image_size.h"
#include "ffloc/io/json_fields.h"
#include "ffloc/data/pose_check.h"

namespace ffloc {
namespace {

using nlohmann::json;

Intrinsics readCamera(const JsonFields& camera) {
  camera.requireKnownKeys({"width", "height", "fx", "fy", "cx", "cy", "distortion"});
  Intrinsics intrinsics;
  intrinsics.width = camera.integer("width");
  intrinsics.height = camera.integer("height");
  intrinsics.fx = camera.number("fx");
  intrinsics.fy = camera.number("fy");
  intrinsics.cx = camera.number("cx");
  intrinsics.cy = camera.number("cy");
  if (camera.has("distortion")) {
    intrinsics.distortion = camera.numbers("distortion");
    const size_t n = intrinsics.distortion.size();
    if (n != 4 && n != 5 && n != 8) camera.fail("distortion", "expected 4, 5 or 8 OpenCV coefficients");
  }
  if (!intrinsics.isValid()) camera.fail("", "invalid intrinsics (need positive focal lengths and image size)");
  const std::string problem = distortionProblem(intrinsics);
  if (!problem.empty()) camera.fail("distortion", problem);
  return intrinsics;
}

Split parseSplit(const JsonFields& frame) {
  if (!frame.has("split")) return Split::kUnassigned;
  const std::string split = frame.string("split");
  for (Split s : {Split::kMapping, Split::kQuery, Split::kUnassigned})
    if (split == toString(s)) return s;
  frame.fail("split", "unknown split '" + split + "' (expected mapping, query or unassigned)");
}

std::string relativeTo(const std::filesystem::path& path, const std::filesystem::path& folder) {
  const auto absolute = std::filesystem::absolute(path).lexically_normal();
  return absolute.lexically_relative(folder).generic_string();
}

}  // namespace

Scene readManifest(const std::filesystem::path& manifest_json) {
  const json root = parseJsonFile(manifest_json);
  const JsonFields top(root, manifest_json, "");
  if (top.string("format") != kManifestFormat)
    top.fail("format", "expected \"" + std::string(kManifestFormat) + "\"");
  if (top.integer("version") != kManifestVersion)
    top.fail("version", "unsupported version " + std::to_string(top.integer("version")) + " (this build reads " +
                            std::to_string(kManifestVersion) + ")");
  top.requireKnownKeys({"format", "version", "name", "metric", "cameras", "frames"});

  const auto folder = std::filesystem::absolute(manifest_json).lexically_normal().parent_path();
  Scene scene;
  scene.root = folder;
  scene.format = "manifest";
  scene.name = top.has("name") ? top.string("name") : folder.filename().string();
  scene.metric = top.has("metric") ? top.boolean("metric") : true;

  std::map<std::string, Intrinsics> cameras;
  const json& camera_list = top.get("cameras");
  if (!camera_list.is_object()) top.fail("cameras", "expected an object of camera id -> camera");
  for (const auto& [id, camera] : camera_list.items())
    cameras[id] = readCamera(JsonFields(camera, manifest_json, "cameras." + id));

  const json& frames = top.get("frames");
  if (!frames.is_array()) top.fail("frames", "expected an array");
  std::set<std::string> names;
  std::map<std::filesystem::path, std::string> frame_of_image;
  for (size_t i = 0; i < frames.size(); ++i) {
    const std::string path = "frames[" + std::to_string(i) + "]";
    const JsonFields entry(frames[i], manifest_json, path);
    entry.requireKnownKeys({"image", "name", "camera", "camera_to_world", "depth", "depth_scale", "depth_invalid",
                            "depth_camera", "split"});
    Frame frame;
    const std::string image = entry.string("image");
    frame.name = entry.has("name") ? entry.string("name") : image;
    // An empty name was mapped, then could not be converted ("images/: cannot write").
    if (frame.name.empty()) entry.fail(entry.has("name") ? "name" : "image", "empty");
    frame.image_path = (folder / image).lexically_normal();
    if (!names.insert(frame.name).second) entry.fail("image", "duplicate frame '" + frame.name + "'");
    // Spelt "./a.png" beside "a.png", one file got two frames with two poses.
    if (const auto [earlier, added] = frame_of_image.emplace(frame.image_path, frame.name); !added)
      entry.fail("image", "'" + image + "' is the image of frame '" + earlier->second + "' too");

    const json& camera_id = entry.get("camera");
    const std::string id = camera_id.is_string() ? camera_id.get<std::string>() : camera_id.dump();
    const auto camera = cameras.find(id);
    if (camera == cameras.end()) entry.fail("camera", "unknown camera id '" + id + "'");
    frame.intrinsics = camera->second;

    const Eigen::Matrix4d T = entry.matrix4("camera_to_world");
    // Checked like every other reader's poses; a rotation as written when it is one to
    // kRigidRotationTolerance, so files round-trip exactly, projected onto one otherwise.
    const std::string problem = poseMatrixProblem(T);
    if (!problem.empty()) entry.fail("camera_to_world", problem);
    frame.camera_to_world = Pose::fromMatrix(T);
    if (orthogonalityError(frame.camera_to_world.R) > kRigidRotationTolerance) projectToRotation(frame.camera_to_world.R);

    if (entry.has("depth")) {
      DepthSource depth;
      depth.path = (folder / entry.string("depth")).lexically_normal();
      if (entry.has("depth_scale")) depth.scale = entry.number("depth_scale");
      if (!(depth.scale > 0) || !std::isfinite(depth.scale)) entry.fail("depth_scale", "must be positive");
      if (entry.has("depth_invalid")) depth.invalid_values = entry.numbers("depth_invalid");
      if (entry.has("depth_camera")) {
        const auto depth_camera = cameras.find(entry.string("depth_camera"));
        if (depth_camera == cameras.end())
          entry.fail("depth_camera", "unknown camera id '" + entry.string("depth_camera") + "'");
        if (!depth_camera->second.distortion.empty()) entry.fail("depth_camera", "must be a pinhole camera (no distortion)");
        depth.camera = depth_camera->second;
      }
      frame.depth = depth;
    }
    frame.split = parseSplit(entry);
    // Read from its header here, as every other reader does: unchecked, a query whose image was
    // missing or not an image at all reached evaluation, where a method that never reads it
    // (oracle-depth) scored it 100 %.
    cv::Size size;
    try {
      size = readImageSize(frame.image_path);
    } catch (const InputError& e) {
      entry.fail("image", e.what());
    }
    if (size.width != frame.intrinsics.width || size.height != frame.intrinsics.height) {
      entry.fail("image", frame.image_path.string() + " is " + std::to_string(size.width) + "x" +
                              std::to_string(size.height) + ", but camera '" + id + "' is " +
                              std::to_string(frame.intrinsics.width) + "x" + std::to_string(frame.intrinsics.height));
    }
    scene.frames.push_back(std::move(frame));
  }
  return scene;
}

void writeManifest(const Scene& scene, const std::filesystem::path& manifest_json) {
  const auto folder = std::filesystem::absolute(manifest_json).lexically_normal().parent_path();
  std::vector<Intrinsics> cameras;
  json frames = json::array();
  auto cameraId = [&](const Intrinsics& intrinsics) {
    size_t camera = 0;
    while (camera < cameras.size() && !sameIntrinsics(cameras[camera], intrinsics)) ++camera;
    if (camera == cameras.size()) cameras.push_back(intrinsics);
    return std::to_string(camera);
  };
  for (const Frame& frame : scene.frames) {
    const std::string camera = cameraId(frame.intrinsics);

    json entry;
    entry["image"] = relativeTo(frame.image_path, folder);
    if (entry["image"].get<std::string>() != frame.name) entry["name"] = frame.name;
    entry["camera"] = camera;
    entry["camera_to_world"] = matrix4Json(frame.camera_to_world.matrix());
    if (frame.depth) {
      entry["depth"] = relativeTo(frame.depth->path, folder);
      entry["depth_scale"] = frame.depth->scale;
      entry["depth_invalid"] = frame.depth->invalid_values;
      if (frame.depth->camera) entry["depth_camera"] = cameraId(*frame.depth->camera);
    }
    entry["split"] = toString(frame.split);
    frames.push_back(std::move(entry));
  }

  json camera_list = json::object();
  for (size_t i = 0; i < cameras.size(); ++i) {
    const Intrinsics& c = cameras[i];
    json camera = {{"width", c.width}, {"height", c.height}, {"fx", c.fx}, {"fy", c.fy}, {"cx", c.cx}, {"cy", c.cy}};
    if (!c.distortion.empty()) camera["distortion"] = c.distortion;
    camera_list[std::to_string(i)] = std::move(camera);
  }

  json root;
  root["format"] = kManifestFormat;
  root["version"] = kManifestVersion;
  root["name"] = scene.name;
  root["metric"] = scene.metric;
  root["cameras"] = std::move(camera_list);
  root["frames"] = std::move(frames);

  std::filesystem::create_directories(folder);
  // nlohmann::json prints doubles in the shortest form that parses back to the same value.
  writeTextFile(manifest_json, root.dump(1) + "\n");
}

bool isManifestFile(const std::filesystem::path& file) {
  std::error_code error;
  const std::filesystem::file_status status = std::filesystem::status(file, error);
  if (status.type() == std::filesystem::file_type::not_found) return false;
  // A manifest.json that cannot be read as a file (a link loop, a FIFO) is still the dataset's
  // manifest: its reader then says what is wrong with it.
  if (error || status.type() != std::filesystem::file_type::regular) return true;
  std::ifstream in(file, std::ios::binary);
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  const json root = json::parse(text, nullptr, false);
  if (root.is_discarded()) {
    // A manifest that does not parse (Python writes NaN, which JSON lacks) is still one, so that
    // its reader can say what is wrong with it instead of "unknown dataset format".
    return text.find('"' + std::string(kManifestFormat) + '"') != std::string::npos;
  }
  return root.is_object() && root.contains("format") && root["format"] == kManifestFormat;
}

}  // namespace ffloc
