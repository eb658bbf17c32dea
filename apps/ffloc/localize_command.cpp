#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>

#include <nlohmann/json.hpp>

#include "command_model.h"
#include "command_options.h"
#include "commands.h"
#include "ffloc/core/error.h"
#include "ffloc/core/progress.h"
#include "ffloc/core/threads.h"
#include "ffloc/eval/exports.h"
#include "ffloc/eval/report.h"
#include "ffloc/io/image.h"
#include "ffloc/io/image_size.h"
#include "ffloc/io/input_file.h"
#include "ffloc/io/map_file.h"
#include "ffloc/core/utf8.h"
#include "ffloc/localization/localization_json.h"
#include "ffloc/pipeline/map_localizer.h"
#include "ffloc/server/localize_request.h"
#include "ffloc/eval/scene_ply.h"

namespace ffloc::cli {
namespace {

struct LocalizeArguments {
  std::string map_path;
  ModelArguments model;
  QueryArguments query;
  std::string image;
  std::string image_list;
  std::string intrinsics;
  std::string distortion;
  std::string poses_path, ply_path;
  bool json = false;
  bool quiet = false;
  std::vector<std::string> flags_given;  // of those that apply to one method only
};

struct Query {
  std::string name;
  std::filesystem::path path;
  Intrinsics intrinsics;  // fx == 0: not given
  std::string list_line;  // "list.txt:3" for a query from --images; empty for --image
  // Why the list's line gives no intrinsics, answered as this query's error while the others run
  // (one line of three numbers stopped a whole list before any query: an outside probe).
  std::string intrinsics_error;

  // "list.txt:3: query 'q.jpg'" for a query from --images, which its errors start with: a focal
  // length out of range named no line of a long list. Empty for --image.
  std::string location() const { return list_line.empty() ? "" : list_line + ": query '" + name + "'"; }
};

// Four numbers apart by commas or spaces. A comma with no number on one side ("500,500,320,240,",
// "500,,500,320") is refused: such text is cut or mistyped, not four numbers.
Intrinsics parseIntrinsics(const std::string& text, const std::string& where) {
  const auto refuse = [&] {
    throw InputError(where + ": intrinsics must be four numbers fx,fy,cx,cy, got '" + text + "'");
  };
  std::string spaced;
  std::istringstream pieces(text + ",");
  for (std::string piece; std::getline(pieces, piece, ',');) {
    if (piece.find_first_not_of(" \t\r") == std::string::npos) refuse();
    spaced += piece + " ";
  }
  std::istringstream stream(spaced);
  Intrinsics k;
  std::string extra;
  if (!(stream >> k.fx >> k.fy >> k.cx >> k.cy) || (stream >> extra)) refuse();
  return k;
}

bool isNumber(const std::string& token) {
  std::istringstream stream(token);
  double value = 0;
  std::string rest;
  return (stream >> value) && !(stream >> rest);
}

// A path as a query list gives it: relative to the list's folder.
std::filesystem::path listedPath(const std::filesystem::path& list, const std::string& text) {
  const std::filesystem::path path(text);
  return path.is_absolute() ? path : list.parent_path() / path;
}

// Where the intrinsics of a list line start when they are there but not four numbers ("q.jpg 500
// 500 320", "my photo.jpg 500 5oo 320 240"): after the text that names an existing image, either
// the text before the trailing numbers or the first field; 0 when neither names a file (then the
// whole line is a path, spaces included).
size_t misgivenIntrinsicsStart(const std::string& line, const std::vector<size_t>& starts, size_t first_number,
                               const std::filesystem::path& list) {
  const auto namesAFile = [&](size_t end) {
    std::string candidate = line.substr(0, end);
    candidate.erase(candidate.find_last_not_of(" \t\r") + 1);
    return std::filesystem::exists(listedPath(list, candidate));
  };
  if (first_number > 0 && first_number < starts.size() && namesAFile(starts[first_number])) return starts[first_number];
  if (starts.size() > 1 && namesAFile(starts[1])) return starts[1];
  return 0;
}

// One query per line: `image_path [fx fy cx cy]`; paths relative to the list's folder; blank
// lines and '#' comments skipped. The intrinsics are the four numbers at the end when there are
// four, the path everything before them, so a path may hold spaces (split at the first space, it was
// refused as "intrinsics must be four numbers").
std::vector<Query> readQueryList(const std::filesystem::path& list, const Intrinsics& fallback) {
  requireRegularFile(list, "query list");  // a FIFO blocked for ever, /dev/zero filled the memory
  std::ifstream file(list, std::ios::binary);
  if (!file) throwInputError(list.string(), 0, "query list: cannot open");
  std::vector<Query> queries;
  std::string line;
  for (int number = 1; std::getline(file, line); ++number) {
    if (number == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);  // a UTF-8 byte order mark
    if (line.find('\0') != std::string::npos)
      throwInputError(list.string(), number, "query list: the line holds a NUL byte, which no path can");
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    const std::string whitespace = " \t\r";
    std::vector<std::string> fields;
    std::vector<size_t> starts;
    for (size_t at = line.find_first_not_of(whitespace); at != std::string::npos;) {
      const size_t end = std::min(line.find_first_of(whitespace, at), line.size());
      starts.push_back(at);
      fields.push_back(line.substr(at, end - at));
      at = line.find_first_not_of(whitespace, end);
    }
    if (fields.empty()) continue;
    // The intrinsics: four numbers at the end, apart by spaces or commas, from field first_number.
    size_t numbers = 0, first_number = fields.size();
    while (first_number > 1 && numbers < 4) {
      size_t pieces = 0;
      bool all_numbers = true;
      std::istringstream split(fields[first_number - 1]);
      for (std::string piece; std::getline(split, piece, ',');) {
        if (piece.empty()) continue;
        ++pieces;
        all_numbers = all_numbers && isNumber(piece);
      }
      if (pieces == 0 || !all_numbers) break;
      numbers += pieces;
      --first_number;
    }
    const bool given = numbers == 4;
    const auto trimmed = [&](const std::string& text) {
      const size_t first = text.find_first_not_of(whitespace);
      return text.substr(first, text.find_last_not_of(whitespace) - first + 1);
    };
    const std::string path = trimmed(given ? line.substr(0, starts[first_number]) : line);
    Query query;
    query.name = path;
    query.path = listedPath(list, path);
    query.list_line = list.string() + ":" + std::to_string(number);
    if (given) {
      try {
        query.intrinsics = parseIntrinsics(line.substr(starts[first_number]), query.location());
      } catch (const InputError& e) {
        query.intrinsics_error = e.what();
      }
    } else if (const size_t image_end = misgivenIntrinsicsStart(line, starts, first_number, list);
               image_end > 0) {
      query.name = trimmed(line.substr(0, image_end));
      query.path = listedPath(list, query.name);
      query.intrinsics_error = query.list_line + ": query '" + query.name +
                               "': intrinsics must be four numbers fx,fy,cx,cy, got '" + trimmed(line.substr(image_end)) +
                               "'";
    } else if (fallback.fx > 0) {
      query.intrinsics = fallback;
    } else {
      query.intrinsics_error = query.list_line + ": query '" + path + "': no intrinsics (add fx fy cx cy or --intrinsics)";
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
  if (r.contains("reason")) std::cout << " (" << r["reason"].get<std::string>() << ")";
  const auto& e = r["evidence"];
  std::cout << ", " << r["method"].get<std::string>() << ", " << r["inliers"] << " inliers of " << r["pnp_correspondences"]
            << std::setprecision(3);
  if (!e["inlier_ratio"].is_null()) std::cout << " (ratio " << e["inlier_ratio"].get<double>();
  if (!e["inlier_spread"].is_null()) std::cout << ", spread " << e["inlier_spread"].get<double>();
  std::cout << (e["inlier_ratio"].is_null() ? "" : ")") << "\n";
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
  for (const char* stage : {"preprocessing", "features", "retrieval", "matching", "pnp", "verification", "total"})
    std::cout << " " << stage << " " << r["timings_ms"][stage].get<double>();
  std::cout << std::defaultfloat << "\n";
}

// `--poses` given the map's path replaced the map with a pose list, exit 0; so did `--ply`, and
// either given a query image or the query list replaced it.
void refuseOutputsOverInputsOrEachOther(const LocalizeArguments& args, const std::vector<Query>& queries) {
  std::vector<std::pair<std::string, std::string>> inputs = {{"the map (--map)", args.map_path},
                                                             {"the query list (--images)", args.image_list}};
  for (const Query& query : queries) inputs.emplace_back("a query image", query.path.string());
  refuseOutputOverInputs("--poses", args.poses_path, inputs);
  inputs.emplace_back("also the output of --poses", args.poses_path);
  refuseOutputOverInputs("--ply", args.ply_path, inputs);
}

// The map decides the method; a flag of the other one would be ignored without a word.
void refuseOptionsOfTheOtherMethod(const LocalizeArguments& args, LocalizationMethod method) {
  for (const std::string& flag : args.flags_given) {
    if (!methodUsesSetting(method, methodSettingOfFlag().at(flag)))
      throw InputError(flag + ": the map is a " + toString(method) + " map, which does not use it");
  }
}

// A phone stores a portrait photo sideways and says in EXIF how to turn it; the decoder turns it,
// and intrinsics of the image as stored then fit it only by chance (the verdict mostly finds a
// principal point that does not fit). Said on stderr, so that the answer's cause is in sight.
void noteExifTurn(const std::filesystem::path& path, const cv::Mat& decoded) {
  const std::optional<ImageHeader> header = fileImageHeader(path);
  if (!header || !header->with_exif || header->size == decoded.size()) return;
  std::cerr << "note: " << path.string() << ": turned upright by its EXIF orientation, from " << header->size.width
            << "x" << header->size.height << " to " << decoded.cols << "x" << decoded.rows
            << "; the intrinsics must be the upright image's\n";
}

int runLocalize(const LocalizeArguments& args) {
  setLibraryThreadCount(args.model.threads);
  if (args.image.empty() == args.image_list.empty()) throw InputError("give exactly one of --image and --images");
  checkOutputPath("--poses", args.poses_path);
  checkOutputPath("--ply", args.ply_path);
  const LocalizeOptions options = localizeOptions(args.query);

  const Intrinsics fallback = args.intrinsics.empty() ? Intrinsics{} : parseIntrinsics(args.intrinsics, "--intrinsics");
  std::vector<Query> queries;
  if (!args.image.empty()) {
    if (args.intrinsics.empty()) throwInputError(args.image, 0, "query intrinsics missing: pass --intrinsics fx,fy,cx,cy");
    queries.push_back({args.image, args.image, fallback});
  } else {
    queries = readQueryList(args.image_list, fallback);
  }
  // As the server and Python take it: a distorted camera's queries were answered `localized`
  // 50 times less accurately than eval's undistorted ones, without a word (an outside probe).
  if (!args.distortion.empty()) {
    const std::vector<double> distortion = parseDistortion(args.distortion);
    for (Query& query : queries) query.intrinsics.distortion = distortion;
  }

  refuseOutputsOverInputsOrEachOther(args, queries);
  // Before the map and the model load: these would fail, or print a replacement character,
  // only after every query had run.
  for (const Query& query : queries) {
    if (args.json && !isUtf8(query.name))
      throwInputError(query.path.string(), 0, "--json: the query name is not UTF-8, which JSON cannot hold; rename the file");
    const std::string problem = args.poses_path.empty() ? "" : poseListNameProblem(query.name);
    if (!problem.empty()) throwInputError(query.path.string(), 0, "--poses: query '" + query.name + "': " + problem);
  }

  // From the header, before a FastForward map loads its network.
  refuseOptionsOfTheOtherMethod(args, parseLocalizationMethod(readMapHeader(args.map_path).method));
  const MapLocalizer opened = openMapLocalizer(args.map_path, [&] { return loadCommandModel(args.model); });
  const Localizer& localizer = *opened.localizer;
  std::cerr << "map: " << opened.description << "; K = " << options.top_k;
  if (localizer.method() == LocalizationMethod::kFastForward)
    std::cerr << ", N = " << options.num_features << ", selection " << toString(options.selection) << ", retrieval "
              << toString(options.retrieval);
  std::cerr << "\n";

  nlohmann::json results = nlohmann::json::array();
  std::vector<FrameResult> poses;
  PlyWriter ply;
  std::vector<std::pair<Pose, Intrinsics>> estimated_cameras;
  bool any_input_error = false, any_not_localized = false;
  // Without --json each answer is printed as it comes; with it nothing was until the last (16 s
  // for redkitchen's 100 queries, found by an outside probe).
  ProgressBar progress("queries", queries.size(), args.quiet || !args.json || queries.size() == 1);
  for (size_t q = 0; q < queries.size(); ++q) {
    const Query& query = queries[q];
    nlohmann::json r;
    // A lone query's bad input ends the command; in a list it is that query's answer.
    const auto answerInputError = [&](const std::string& error) {
      if (queries.size() == 1) throw InputError(error);
      r = {{"name", query.name}, {"status", "error"}, {"error", error}};
      any_input_error = true;
    };
    if (!query.intrinsics_error.empty()) {
      answerInputError(query.intrinsics_error);
    } else {
      try {
        const cv::Mat image = readImageRgb(query.path);
        noteExifTurn(query.path, image);
        const LocalizationResult result = localizer.localize(image, query.intrinsics, query.name, options);
        r = localizationJson(query.name, result, localizer);
        FrameResult frame;
        frame.frame = query.name;
        frame.status = result.pnp.status;
        frame.verdict = result.verdict.status;
        frame.estimate = result.pnp.camera_to_world;
        frame.inliers = result.pnp.inliers;
        // The pose list is for poses to use: an `uncertain` one (a query from another scene, 1-7 m
        // off) read as any other there (an outside probe). Its status and pose stay in the answer.
        if (result.localized()) poses.push_back(frame);
        any_not_localized |= !result.localized();
        if (q == 0 && !args.ply_path.empty()) {
          addPredictedPoints(ply, result.correspondences, options.pnp.confidence_threshold, 50000, PlyWriter::kRed);
        }
        if (result.pnp.ok()) estimated_cameras.emplace_back(result.pnp.camera_to_world, result.camera);
      } catch (const InputError& e) {
        // An --image query's error named neither it nor the flag when about its intrinsics; one that
        // names a flag or the image says enough.
        const std::string what = withFlagName(e.what());
        const bool named = what.rfind("--", 0) == 0 || what.find(query.path.string()) != std::string::npos;
        // Named, it was named twice: "list.txt:3: query 'q.png': q.png: image: ...".
        const std::string location = named                     ? query.list_line
                                     : !query.list_line.empty() ? query.location()
                                                                : "query '" + query.path.string() + "'";
        answerInputError(location.empty() ? what : location + ": " + what);
      }
    }
    if (!args.json) printText(r);
    results.push_back(r);
    progress.update(q + 1);
  }
  progress.finish();
  if (args.json) std::cout << jsonText(queries.size() == 1 ? results[0] : results, 2) << "\n";

  if (!args.poses_path.empty()) {
    writeTextFile(args.poses_path, hlocPoseList(poses));
    std::cerr << "wrote " << args.poses_path << " (the poses of the " << poses.size() << " localized of "
              << queries.size() << " queries)\n";
  }
  if (!args.ply_path.empty()) {
    std::vector<Pose> cameras;
    for (const MapCamera& camera : localizer.cameras()) cameras.push_back(camera.camera_to_world);
    const double size = cameraGlyphSize(cameras);
    for (const MapCamera& camera : localizer.cameras())
      ply.addCamera(camera.camera_to_world, camera.intrinsics, size, PlyWriter::kGrey);
    for (const auto& [pose, camera] : estimated_cameras) ply.addCamera(pose, camera, size, PlyWriter::kBlue);
    ply.write(args.ply_path);
    std::cerr << "wrote " << args.ply_path << "\n";
  }
  return any_input_error ? 2 : (any_not_localized ? 1 : 0);
}

}  // namespace

void registerLocalizeCommand(CLI::App& app, CommandRun& run) {
  auto args = std::make_shared<LocalizeArguments>();
  CLI::App* cmd = app.add_subcommand(
      "localize",
      "Localise query images against a map from 'ffloc map', with the method the map was built with. Every answer "
      "has a status: localized (use the pose), uncertain (a pose is given, but the evidence is weak) or failed. Exit "
      "code 0 when every query is localized, 1 otherwise, 2 for bad input.");
  cmd->add_option("--map", args->map_path, "Map file from 'ffloc map'")->required();
  addModelOptions(*cmd, args->model, "fastforward maps: the model the map was built with (as for 'ffloc map')");
  addQueryOptions(*cmd, args->query);
  cmd->add_option("--image", args->image, "Query image");
  cmd->add_option("--images", args->image_list,
                  "Text file, one query per line: image path (relative to the file; spaces allowed) [fx fy cx cy]");
  cmd->add_option("--intrinsics", args->intrinsics, "Query pinhole intrinsics fx,fy,cx,cy in pixels of the image");
  cmd->add_option("--distortion", args->distortion,
                  "The query camera's lens distortion, OpenCV's k1,k2,p1,p2[,k3[,k4,k5,k6]], for every query");
  cmd->add_option("--poses", args->poses_path, "Write the poses of the localized queries as an hloc pose list");
  cmd->add_option("--ply", args->ply_path,
                  "Write a PLY: mapping cameras (grey), estimated query cameras (blue), the first query's "
                  "correspondences' points with confidence >= 1.5 (red)");
  cmd->add_flag("--json", args->json, "Print JSON (an object for one query, an array for a list)");
  cmd->add_flag("--quiet", args->quiet, "No progress bar (--images with --json draws one on stderr)");
  for (const char* path_flag : {"--map", "--image", "--images", "--poses", "--ply"})
    cmd->get_option(path_flag)->check(nonEmptyPath());
  cmd->callback([args, cmd, &run] {
    args->flags_given = flagsGiven(*cmd, methodSettingOfFlag());
    run = [args] { return runLocalize(*args); };
  });
}

}  // namespace ffloc::cli
