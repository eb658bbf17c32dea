#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>

#include <nlohmann/json.hpp>

#include "command_model.h"
#include "commands.h"
#include "ffloc/core/error.h"
#include "ffloc/eval/exports.h"
#include "ffloc/eval/report.h"
#include "ffloc/io/image.h"
#include "ffloc/pipeline/localization_json.h"
#include "ffloc/pipeline/localizer.h"
#include "ffloc/pipeline/model_loader.h"
#include "ffloc/pipeline/scene_ply.h"

namespace ffloc::cli {
namespace {

struct LocalizeArguments {
  std::string map_path;
  std::string model = "default";
  std::string image;
  std::string image_list;
  std::string intrinsics;
  std::string preset = "indoor";
  size_t top_k = 0;        // 0: the preset's
  int64_t features = 0;    // 0: the preset's
  uint64_t seed = 0;
  std::string selection = "retrieval";
  std::string solver = "lo-ransac";
  std::string dtype = "f32";
  std::string poses_path, ply_path;
  int threads = 0;
  bool json = false;
};

struct Query {
  std::string name;
  std::filesystem::path path;
  Intrinsics intrinsics;  // fx == 0: not given
};

// "fx,fy,cx,cy" (commas or spaces).
Intrinsics parseIntrinsics(const std::string& text, const std::string& where) {
  std::string spaced = text;
  for (char& c : spaced)
    if (c == ',') c = ' ';
  std::istringstream stream(spaced);
  Intrinsics k;
  std::string extra;
  if (!(stream >> k.fx >> k.fy >> k.cx >> k.cy) || (stream >> extra) || !(k.fx > 0 && k.fy > 0))
    throw InputError(where + ": intrinsics must be four numbers fx,fy,cx,cy with fx, fy > 0, got '" + text + "'");
  return k;
}

// One query per line: `image_path [fx fy cx cy]`; paths relative to the list's folder; blank
// lines and '#' comments skipped.
std::vector<Query> readQueryList(const std::filesystem::path& list, const Intrinsics& fallback) {
  std::ifstream file(list);
  if (!file) throwInputError(list.string(), 0, "query list: cannot open");
  std::vector<Query> queries;
  std::string line;
  for (int number = 1; std::getline(file, line); ++number) {
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream stream(line);
    std::string path;
    if (!(stream >> path)) continue;
    Query query;
    query.name = path;
    query.path = std::filesystem::path(path).is_absolute() ? std::filesystem::path(path) : list.parent_path() / path;
    std::string rest;
    std::getline(stream, rest);
    if (rest.find_first_not_of(" \t\r") != std::string::npos) {
      query.intrinsics = parseIntrinsics(rest, locate(list.string(), number, "query '" + path + "'"));
    } else if (fallback.fx > 0) {
      query.intrinsics = fallback;
    } else {
      throwInputError(list.string(), number, "query '" + path + "': no intrinsics (add fx fy cx cy or --intrinsics)");
    }
    queries.push_back(query);
  }
  if (queries.empty()) throwInputError(list.string(), 0, "query list: no queries");
  return queries;
}

void printText(const nlohmann::json& r) {
  std::cout << r["name"].get<std::string>() << ": " << r["status"].get<std::string>();
  if (r.contains("error")) {
    std::cout << ": " << r["error"].get<std::string>() << "\n";
    return;
  }
  std::cout << ", " << r["inliers"] << " inliers of " << r["pnp_correspondences"] << " (confidence "
            << std::setprecision(3) << r["confidence"].get<double>() << ")\n";
  if (r.contains("camera_to_world")) {
    std::cout << "  camera_to_world:\n" << std::setprecision(6);
    for (const auto& row : r["camera_to_world"]) {
      std::cout << "   ";
      for (const auto& v : row) std::cout << " " << std::setw(12) << v.get<double>();
      std::cout << "\n";
    }
    const auto& w2c = r["world_to_camera"];
    std::cout << "  world_to_camera: q (w x y z) =";
    for (const auto& v : w2c["qwxyz"]) std::cout << " " << v.get<double>();
    std::cout << ", t =";
    for (const auto& v : w2c["t"]) std::cout << " " << v.get<double>();
    std::cout << "\n";
  }
  std::cout << "  selected:";
  for (const auto& name : r["selected"]) std::cout << " " << name.get<std::string>();
  std::cout << "\n  time (ms):" << std::fixed << std::setprecision(1);
  for (const char* stage : {"preprocessing", "retrieval", "encoding", "decoding", "pnp", "total"})
    std::cout << " " << stage << " " << r["timings_ms"][stage].get<double>();
  std::cout << std::defaultfloat << "\n";
}

void runLocalize(const LocalizeArguments& args) {
  if (args.image.empty() == args.image_list.empty()) throw InputError("give exactly one of --image and --images");
  LocalizeOptions options = LocalizeOptions::preset(args.preset);
  if (args.top_k > 0) options.top_k = args.top_k;
  if (args.features > 0) options.num_features = args.features;
  options.seed = args.seed;
  options.selection = parseImageSelection(args.selection);
  options.pnp.solver = parsePnpSolver(args.solver);
  options.pnp.seed = args.seed;

  const Intrinsics fallback = args.intrinsics.empty() ? Intrinsics{} : parseIntrinsics(args.intrinsics, "--intrinsics");
  std::vector<Query> queries;
  if (!args.image.empty()) {
    if (fallback.fx <= 0) throwInputError(args.image, 0, "query intrinsics missing: pass --intrinsics fx,fy,cx,cy");
    queries.push_back({args.image, args.image, fallback});
  } else {
    queries = readQueryList(args.image_list, fallback);
  }

  const LoadedModel model = loadCommandModel(args.model, args.dtype, args.threads);
  const Localizer localizer(*model.model, readMapFile(args.map_path, model.id));
  const MapFile& map = localizer.map();
  std::cerr << "map: " << map.images.size() << " images; K = " << options.top_k << ", N = " << options.num_features
            << ", selection " << toString(options.selection) << "\n";

  nlohmann::json results = nlohmann::json::array();
  std::vector<FrameResult> poses;
  PlyWriter ply;
  std::vector<std::pair<Pose, Intrinsics>> estimated_cameras;
  bool any_input_error = false, any_failure = false;
  for (size_t q = 0; q < queries.size(); ++q) {
    const Query& query = queries[q];
    nlohmann::json r;
    try {
      const LocalizationResult result = localizer.localize(readImageRgb(query.path), query.intrinsics, query.name, options);
      r = localizationJson(query.name, result, map);
      FrameResult frame;
      frame.frame = query.name;
      frame.status = result.pnp.status;
      frame.estimate = result.pnp.camera_to_world;
      frame.inliers = result.pnp.inliers;
      poses.push_back(frame);
      any_failure |= !result.pnp.ok();
      if (q == 0 && !args.ply_path.empty()) {
        addPredictedPoints(ply, result.prediction.correspondences, options.pnp.confidence_threshold, 50000,
                           PlyWriter::kRed);
      }
      if (result.pnp.ok()) estimated_cameras.emplace_back(result.pnp.camera_to_world, result.prediction.camera);
    } catch (const InputError& e) {
      if (queries.size() == 1) throw;
      r = {{"name", query.name}, {"status", "error"}, {"error", e.what()}};
      any_input_error = true;
    }
    if (!args.json) printText(r);
    results.push_back(r);
  }
  if (args.json) std::cout << (queries.size() == 1 ? results[0] : results).dump(2) << "\n";

  if (!args.poses_path.empty()) {
    writeTextFile(args.poses_path, hlocPoseList(poses));
    std::cerr << "wrote " << args.poses_path << "\n";
  }
  if (!args.ply_path.empty()) {
    std::vector<Pose> cameras;
    for (const MapImage& image : map.images) cameras.push_back(image.camera_to_world);
    const double size = cameraGlyphSize(cameras);
    for (const MapImage& image : map.images) ply.addCamera(image.camera_to_world, image.intrinsics, size, PlyWriter::kGrey);
    for (const auto& [pose, camera] : estimated_cameras) ply.addCamera(pose, camera, size, PlyWriter::kBlue);
    ply.write(args.ply_path);
    std::cerr << "wrote " << args.ply_path << "\n";
  }
  exitCode() = any_input_error ? 2 : (any_failure ? 1 : 0);
}

}  // namespace

void registerLocalizeCommand(CLI::App& app) {
  auto args = std::make_shared<LocalizeArguments>();
  CLI::App* cmd = app.add_subcommand(
      "localize",
      "Localise query images against a map from 'ffloc map': select K mapping images, sample N of their tokens, "
      "predict the query's 3D coordinates in one forward pass, then PnP-RANSAC. Exit code 1 when a query could not "
      "be localised, 2 for bad input.");
  cmd->add_option("--map", args->map_path, "Map file from 'ffloc map'")->required();
  cmd->add_option("--model", args->model, "The model the map was built with (same forms as for 'ffloc map')")
      ->capture_default_str();
  cmd->add_option("--image", args->image, "Query image");
  cmd->add_option("--images", args->image_list,
                  "Text file, one query per line: image path (relative to the file) [fx fy cx cy]");
  cmd->add_option("--intrinsics", args->intrinsics, "Query pinhole intrinsics fx,fy,cx,cy in pixels of the image");
  cmd->add_option("--preset", args->preset, "indoor (K=10, N=1500) or outdoor (K=20, N=3000)")->capture_default_str();
  cmd->add_option("--top-k", args->top_k, "Mapping images per query (overrides the preset)");
  cmd->add_option("--features", args->features, "Map tokens per query (overrides the preset)");
  cmd->add_option("--seed", args->seed, "Seed of the token sampling, random selection and RANSAC")->capture_default_str();
  cmd->add_option("--selection", args->selection, "Mapping image selection: retrieval, uniform or random")
      ->capture_default_str();
  cmd->add_option("--solver", args->solver, "PnP-RANSAC solver: lo-ransac or opencv-usac")->capture_default_str();
  cmd->add_option("--dtype", args->dtype, "Network precision: f32, or bf16 (encoder, decoder and DPT head)")->capture_default_str();
  cmd->add_option("--threads", args->threads, "libtorch threads (0 = all cores)")->capture_default_str();
  cmd->add_option("--poses", args->poses_path, "Write the estimated poses as an hloc pose list");
  cmd->add_option("--ply", args->ply_path,
                  "Write a PLY: mapping cameras (grey), estimated query cameras (blue), the first query's predicted "
                  "points with confidence >= 1.5 (red)");
  cmd->add_flag("--json", args->json, "Print JSON (an object for one query, an array for a list)");
  cmd->callback([args] { runLocalize(*args); });
}

}  // namespace ffloc::cli
