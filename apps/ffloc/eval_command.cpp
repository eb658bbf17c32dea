#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>

#include "command_options.h"
#include "commands.h"
#include "ffloc/classical/classical_localizer.h"
#include "ffloc/core/error.h"
#include "ffloc/core/text_file_writer.h"
#include "ffloc/core/threads.h"
#include "ffloc/core/utf8.h"
#include "ffloc/data/dataset.h"
#include "ffloc/data/splits.h"
#include "ffloc/eval/evaluator.h"
#include "ffloc/eval/exports.h"
#include "ffloc/eval/html_report.h"
#include "ffloc/eval/method_evaluation.h"
#include "ffloc/eval/protocol.h"
#include "ffloc/eval/report.h"
#include "ffloc/eval/scene_ply.h"
#include "ffloc/io/input_file.h"
#include "ffloc/io/map_file.h"
#ifdef FFLOC_WITH_TORCH
#include "command_model.h"
#include "ffloc/pipeline/map_building.h"
#include "ffloc/pipeline/map_localizer.h"
#endif

namespace ffloc::cli {
namespace {

struct EvalArguments {
  std::vector<std::string> datasets;
  std::string format = "auto";
  std::string methods;  // empty: classical, or only the map with --map
  std::string json_path, csv_path, markdown_path, html_path;
  double outliers = 0.0;
  double noise_px = 0.0;
  double point_noise = 0.0;
  int stride = 4;
  size_t max_queries = 0;
  double inlier_threshold_px = PnpOptions().inlier_threshold_px;
  float confidence_threshold = PnpOptions().confidence_threshold;
  size_t max_correspondences = PnpOptions().max_correspondences;
  size_t min_correspondences = PnpOptions().min_correspondences;
  QueryArguments query;
#ifdef FFLOC_WITH_TORCH
  ModelArguments model;
#endif
  std::string map_path;
  std::vector<std::string> method_flags_given;
  std::vector<std::string> evaluation_flags_given;
  std::vector<std::string> study_only_pnp_flags_given;
  std::string poses_path, ply_path;
  bool no_depth = false;
  std::string protocol;
  bool quiet = false;
};

std::vector<std::string> splitList(const std::string& text) {
  std::vector<std::string> items;
  std::stringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ','))
    if (!item.empty()) items.push_back(item);
  return items;
}

#ifdef FFLOC_WITH_TORCH
// Loaded once and shared by the methods of every dataset.
const LoadedModel& sharedModel(const EvalArguments& args) {
  static std::unique_ptr<const LoadedModel> model;
  if (!model) model = std::make_unique<const LoadedModel>(loadCommandModel(args.model));
  return *model;
}
#endif

// The flags of one evaluation method run in memory, with it: taken without a word when it does not
// run (--stride with classical alone; --no-depth beside a saved map, built with its points already).
const std::map<std::string, std::string>& evaluationMethodOfFlag() {
  static const std::map<std::string, std::string> method_of_flag = {{"--outliers", "oracle-depth"},
                                                                    {"--noise-px", "oracle-depth"},
                                                                    {"--point-noise", "oracle-depth"},
                                                                    {"--stride", "oracle-depth"},
                                                                    {"--no-depth", "classical"}};
  return method_of_flag;
}

// The output files a run was asked for: (flag, path).
std::vector<std::pair<std::string, std::string>> outputsAsked(const EvalArguments& args) {
  std::vector<std::pair<std::string, std::string>> outputs;
  for (const auto& [flag, path] : {std::pair<const char*, const std::string&>{"--json", args.json_path},
                                   {"--csv", args.csv_path},
                                   {"--markdown", args.markdown_path},
                                   {"--html", args.html_path},
                                   {"--poses", args.poses_path},
                                   {"--ply", args.ply_path}})
    if (!path.empty()) outputs.emplace_back(flag, path);
  return outputs;
}

// Where the per-frame CSV and the markdown table go: as named, else beside --json (nothing is
// beside /dev/stdout); empty for none.
struct TableOutputs {
  std::string csv, markdown;
};
TableOutputs tableOutputs(const EvalArguments& args) {
  TableOutputs outputs{args.csv_path, args.markdown_path};
  if (!args.json_path.empty() && !writesThrough(args.json_path)) {
    const std::string stem = std::filesystem::path(args.json_path).replace_extension().string();
    if (outputs.csv.empty()) outputs.csv = stem + ".frames.csv";
    if (outputs.markdown.empty()) outputs.markdown = stem + ".md";
  }
  return outputs;
}

// The outputs asked for and the files --json puts beside it unless told otherwise.
std::vector<std::pair<std::string, std::string>> outputsWritten(const EvalArguments& args) {
  std::vector<std::pair<std::string, std::string>> outputs = outputsAsked(args);
  const TableOutputs tables = tableOutputs(args);
  if (args.csv_path.empty() && !tables.csv.empty()) outputs.emplace_back("--json (its CSV)", tables.csv);
  if (args.markdown_path.empty() && !tables.markdown.empty()) outputs.emplace_back("--json (its table)", tables.markdown);
  return outputs;
}

// An HTML report given a query image's path replaced the image, exit 0, and the dataset no
// longer read back; two outputs of one path kept only the last. Outputs go beside the data, each
// to its own file.
void refuseOutputsOverInputsOrEachOther(const EvalArguments& args) {
  const std::vector<std::pair<std::string, std::string>> outputs = outputsWritten(args);
  for (size_t i = 0; i < outputs.size(); ++i) {
    const auto& [flag, path] = outputs[i];
    for (size_t j = 0; j < i; ++j)
      if (sameFolderKey(path) == sameFolderKey(outputs[j].second))
        throw InputError(flag + ": '" + path + "' is also the output of " + outputs[j].first);
    refuseOutputOverInputs(flag, path, {{"the map being evaluated", args.map_path}}, args.datasets);
  }
}

// A manifest may name files outside its folder (../elsewhere/x.png), which the folder check
// cannot see: an output given such a path replaced a query's image with the run's CSV, exit 0.
// An output that already exists is refused when it is a file the dataset reads: a frame's image or
// depth map wherever it lies, or any file under the dataset's folder, links followed. Only images
// and depth were compared before, so an output that was the target of a linked manifest.json,
// pose file or split list replaced the dataset's ground truth (found by an outside probe).
void refuseOutputsOverFilesOf(const Scene& scene, const EvalArguments& args) {
  namespace fs = std::filesystem;
  using FileId = std::pair<dev_t, ino_t>;
  const auto idOf = [](const fs::path& path) -> std::optional<FileId> {
    struct stat info {};
    if (::stat(path.c_str(), &info) != 0 || !S_ISREG(info.st_mode)) return std::nullopt;
    return FileId{info.st_dev, info.st_ino};
  };
  std::map<FileId, std::pair<std::string, std::string>> outputs;  // the flag and path of each
  for (const auto& [flag, path] : outputsWritten(args))
    if (const auto id = idOf(path)) outputs.emplace(*id, std::make_pair(flag, path));
  if (outputs.empty()) return;
  const auto refuseIfOutput = [&](const fs::path& file) {
    const auto id = idOf(file);
    if (!id || !outputs.count(*id)) return;
    const auto& [flag, path] = outputs.at(*id);
    throw InputError(flag + ": '" + path + "' is a file of the dataset " + scene.root.string() +
                     (fs::path(path) == file ? "" : " (as " + file.string() + ")") + "; write it elsewhere");
  };
  for (const Frame& frame : scene.frames) {
    refuseIfOutput(frame.image_path);
    if (frame.depth) refuseIfOutput(frame.depth->path);
  }
  std::error_code error;
  const auto options = fs::directory_options::follow_directory_symlink | fs::directory_options::skip_permission_denied;
  for (fs::recursive_directory_iterator entry(scene.root, options, error), end; !error && entry != end;
       entry.increment(error)) {
    if (entry.depth() >= 8) entry.disable_recursion_pending();  // a loop of links ends here
    refuseIfOutput(entry->path());
  }
}

// Datasets of one name (every seed of `ffloc synth` has a scene_000_indoor) gave rows nothing told
// apart: those are named by their folder as given instead. A name that is not UTF-8 (a folder's)
// is written with \xhh escapes: the summary JSON cannot hold it, and its writer failed after the
// whole evaluation, losing every output.
void nameScenesApart(std::vector<Scene>& scenes, const std::vector<std::string>& folders) {
  std::map<std::string, int> uses;
  for (const Scene& scene : scenes) ++uses[scene.name];
  for (size_t i = 0; i < scenes.size(); ++i) {
    if (uses[scenes[i].name] > 1) scenes[i].name = folders[i];
    scenes[i].name = escapeInvalidUtf8(scenes[i].name);
  }
}

int runEval(const EvalArguments& args) {
#ifdef FFLOC_WITH_TORCH
  setLibraryThreadCount(args.model.threads);
#endif
  std::vector<std::string> methods = splitList(args.methods);
  if (methods.empty() && args.map_path.empty()) methods = {"classical"};
  // Written as "not in range" so that NaN, which fails every comparison, is refused too.
  if (!(args.outliers >= 0 && args.outliers <= 1)) throw InputError("--outliers: must be in [0, 1]");
  if (!(args.noise_px >= 0 && std::isfinite(args.noise_px)))
    throw InputError("--noise-px: must be a finite number of pixels, 0 or more");
  if (!(args.point_noise >= 0 && std::isfinite(args.point_noise)))
    throw InputError("--point-noise: must be a finite distance, 0 or more");
  for (const auto& [flag, path] : outputsWritten(args)) checkOutputPath(flag, path);  // named by --json too
  if (!args.map_path.empty() && args.datasets.size() != 1) throw InputError("--map: a map serves exactly one dataset");
  std::vector<std::string> evaluated = methods;
  if (!args.map_path.empty()) evaluated.push_back(readMapHeader(args.map_path).method);
  for (const std::string& flag : args.method_flags_given)
    if (const std::string problem = settingNoMethodUsesProblem(evaluated, methodSettingOfFlag().at(flag));
        !problem.empty())
      throw InputError(flag + ": " + problem);
  // A saved map's row is what 'ffloc localize' would answer; with these it answered what no
  // deployment can (an outside review tuned --inlier-threshold on a map's row).
  if (!args.map_path.empty() && !args.study_only_pnp_flags_given.empty())
    throw InputError(args.study_only_pnp_flags_given.front() +
                     ": 'ffloc localize' does not take it, so the map's row would not be what it answers; study it "
                     "on methods built in memory (--methods, without --map)");
  for (const std::string& flag : args.evaluation_flags_given) {
    const std::string& method = evaluationMethodOfFlag().at(flag);
    if (std::find(methods.begin(), methods.end(), method) != methods.end()) continue;
    // With --map alone the message blamed a --methods never given, beside a classical map.
    if (!args.map_path.empty() && std::find(evaluated.begin(), evaluated.end(), method) != evaluated.end())
      throw InputError(flag + ": the map's was set when 'ffloc map' built it; only " + method +
                       " built in memory (--methods " + method + ") uses it here");
    throw InputError(flag + ": only " + method + " uses it, and --methods does not run it");
  }
  for (size_t i = 0; i < args.datasets.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      if (sameFolderKey(args.datasets[i]) == sameFolderKey(args.datasets[j]))
        throw InputError("--dataset: '" + args.datasets[i] + "' is given twice");
  refuseOutputsOverInputsOrEachOther(args);
  const size_t rows = methods.size() + (args.map_path.empty() ? 0 : 1);
  if (!args.poses_path.empty() && (rows != 1 || args.datasets.size() != 1))
    throw InputError("--poses: needs exactly one dataset and one method");
  if (!args.ply_path.empty() && args.datasets.size() != 1) throw InputError("--ply: needs exactly one dataset");
  LocalizeOptions localize = localizeOptions(args.query);
  if (!args.protocol.empty()) {
    const BenchmarkProtocol& protocol = benchmarkProtocol(args.protocol);
    if (args.query.top_k_option->count() == 0) localize.top_k = protocol.top_k;
    if (args.query.features_option->count() == 0) localize.num_features = protocol.features;
  }

  EvaluationOptions options;
  options.pnp = localize.pnp;
  options.pnp.inlier_threshold_px = args.inlier_threshold_px;
  options.pnp.confidence_threshold = args.confidence_threshold;
  options.pnp.max_correspondences = args.max_correspondences;
  options.pnp.min_correspondences = args.min_correspondences;
  options.verdict = localize.verdict;
  options.max_queries = args.max_queries;
  options.quiet = args.quiet;
  {
    LocalizeOptions checked = localize;
    checked.pnp = options.pnp;
    checked.check();
  }

  MethodEvaluationOptions method_options;
  method_options.evaluation = options;
  method_options.localize = localize;
  method_options.oracle_depth.outlier_fraction = args.outliers;
  method_options.oracle_depth.pixel_noise_px = args.noise_px;
  method_options.oracle_depth.point_noise = args.point_noise;
  method_options.oracle_depth.stride = args.stride;
  method_options.use_depth = !args.no_depth;
#ifdef FFLOC_WITH_TORCH
  method_options.fastforward = [&](const Scene& scene) {
    MappingOptions mapping;
    mapping.quiet = args.quiet;
    mapping.vlad = localize.retrieval == FastForwardRetrieval::kVlad;
    return inMemoryFastForwardLocalizer(sharedModel(args), scene, mapping);
  };
#endif

  // The PLY shows one method's poses (and, for a localizer, the last query's points): the map's
  // when there is one, else fastforward's when it runs, else the first method's.
  std::string ply_method = methods.empty() ? "" : methods.front();
  if (std::find(methods.begin(), methods.end(), "fastforward") != methods.end()) ply_method = "fastforward";

  std::vector<FrameResult> all_frames;
  std::vector<MethodSummary> summaries;
  std::vector<std::string> non_metric;
  std::vector<ReportDataset> report_datasets;
  // Every dataset is read and checked before the first is evaluated: a bad last one was found
  // only after the others' evaluation.
  std::vector<Scene> scenes;
  for (const std::string& dataset : args.datasets) {
    Scene scene = loadDataset(dataset, args.format);
    refuseOutputsOverFilesOf(scene, args);
    // Up front: classical would map an empty split and blame the features ("no mapping image has
    // usable features"), and map a full one before finding no query to evaluate.
    if (!methods.empty()) requireSplits(scene);
    if (!args.poses_path.empty()) {
      for (const size_t index : scene.indices(Split::kQuery)) {
        const Frame& frame = scene.frames[index];
        const std::string problem = poseListNameProblem(frame.name);
        if (!problem.empty())
          throwInputError(frame.image_path.string(), 0, "--poses: frame '" + frame.name + "': " + problem);
      }
    }
    scenes.push_back(std::move(scene));
  }
  nameScenesApart(scenes, args.datasets);
  for (Scene& scene : scenes) {
    if (!args.protocol.empty()) {
      // Thinned by the frames' capture numbers: said, as other data (renumbered, or not 7-Scenes)
      // lost most of its mapping frames without a word.
      const size_t before = scene.mappingIndices().size();
      thinMappingFrames(scene, benchmarkProtocol(args.protocol).mapping_stride);
      if (scene.mappingIndices().size() != before)
        std::cerr << scene.name << ": protocol " << args.protocol << " keeps " << scene.mappingIndices().size()
                  << " of its " << before << " mapping frames (every "
                  << benchmarkProtocol(args.protocol).mapping_stride
                  << "th by capture number, for the benchmark's 30 Hz scans; other data loses most of its map)\n";
    }
    if (!scene.metric) non_metric.push_back(scene.name);
    if (!args.html_path.empty()) report_datasets.push_back(reportDataset(scene));
    auto record = [&](const std::vector<FrameResult>& frames, const std::string& method, const Correspondences* points) {
      summaries.push_back(summarize(frames));
      all_frames.insert(all_frames.end(), frames.begin(), frames.end());
      if (!args.ply_path.empty() && method == ply_method) {
        evaluationPly(scene, frames, points, options.pnp.confidence_threshold).write(args.ply_path);
        std::cerr << "wrote " << args.ply_path << "\n";
      }
    };
    Correspondences last_points;
    const LocalizationObserver keep_points = [&](const Frame&, const LocalizationResult& result) {
      last_points = result.correspondences;
    };
    for (const std::string& method : methods) {
      const std::vector<FrameResult> frames = evaluateMethod(scene, method, method_options, keep_points);
      const bool localizes = method == "classical" || method == "fastforward";
      record(frames, method, localizes ? &last_points : nullptr);
    }
    if (!args.map_path.empty()) {
#ifdef FFLOC_WITH_TORCH
      const MapLocalizer opened = openMapLocalizer(args.map_path, [&] { return loadCommandModel(args.model); });
      const Localizer& localizer = *opened.localizer;
#else
      const ClassicalLocalizer localizer(readClassicalMap(args.map_path));
#endif
      const std::string label = std::string(toString(localizer.method())) + "@map";
      for (const std::string& warning : mapScoringWarnings(scene, localizer.cameras()))
        std::cerr << "warning: --map '" << args.map_path << "': " << warning << "\n";
      if (ply_method.empty()) ply_method = label;
      record(evaluateLocalizer(scene, localizer, label, localize, options, keep_points), label, &last_points);
      methods.push_back(label);
    }
  }

  // Several metric datasets: one more row per method over all their frames. Thresholds in metres
  // mean nothing for a dataset of arbitrary scale, so such a mix gets no pooled row.
  if (args.datasets.size() > 1 && non_metric.empty()) {
    const std::string label = "all " + std::to_string(args.datasets.size()) + " datasets";
    for (const std::string& method : methods) summaries.push_back(summarizePooled(all_frames, method, label));
  }
  const std::string table = markdownTable(summaries, non_metric);
  std::cout << table;
  const std::string protocol_text =
      args.protocol.empty() ? "" : describeProtocol(benchmarkProtocol(args.protocol), localize.top_k, localize.num_features);
  std::cerr << protocol_text;
  const auto [csv_path, markdown_path] = tableOutputs(args);
  if (!args.json_path.empty()) {
    nlohmann::json summary = summaryJson(summaries, non_metric);
    if (!args.protocol.empty()) {
      const BenchmarkProtocol& protocol = benchmarkProtocol(args.protocol);
      summary["protocol"] = {{"name", protocol.name},
                             {"paper_tables", protocol.paper_tables},
                             {"top_k", localize.top_k},
                             {"features", localize.num_features},
                             {"mapping_stride", protocol.mapping_stride},
                             {"reported_accuracies", protocol.accuracy_keys},
                             {"medians", protocol.medians}};
    }
    writeTextFile(args.json_path, summary.dump(2) + "\n");
    std::cerr << "wrote " << args.json_path << "\n";
  }
  if (!csv_path.empty()) {
    writeTextFile(csv_path, perFrameCsv(all_frames));
    std::cerr << "wrote " << csv_path << "\n";
  }
  if (!markdown_path.empty()) {
    // The protocol's line beside the table, as printed: the table alone did not say how it was made.
    writeTextFile(markdown_path, protocol_text.empty() ? table : table + "\n" + protocol_text);
    std::cerr << "wrote " << markdown_path << "\n";
  }
  if (!args.poses_path.empty()) {
    writeTextFile(args.poses_path, hlocPoseList(all_frames));
    std::cerr << "wrote " << args.poses_path << "\n";
  }
  if (!args.html_path.empty()) {
    // The protocol's line under the table, as in the .md (it was left out, an outside probe).
    writeTextFile(args.html_path, htmlReport(summaries, all_frames, report_datasets, protocol_text));
    std::cerr << "wrote " << args.html_path << "\n";
  }
  return 0;
}

}  // namespace

void registerEvalCommand(CLI::App& app, CommandRun& run) {
  auto args = std::make_shared<EvalArguments>();
  CLI::App* cmd = app.add_subcommand(
      "eval", "Localise every query frame of one or more datasets with one or more methods, and report pose "
              "accuracy (medians; % within 5cm/5deg, 10cm/10deg, 20cm/20deg, 10cm/1deg, 25cm/5deg) and latency.");
  cmd->add_option("--dataset", args->datasets, "Dataset folder(s); the format is detected (comma-separated for several)")
      ->required()
      ->check(nonEmptyPath())
      ->delimiter(',');
  cmd->add_option("--format", args->format, "Dataset format: auto, " + [] {
        std::string s;
        for (const auto& f : datasetFormats()) s += (s.empty() ? "" : ", ") + f;
        return s;
      }())->capture_default_str();
  cmd->add_option("--methods", args->methods,
                 "Comma-separated: classical (the default), sift-baseline, oracle-depth"
#ifdef FFLOC_WITH_TORCH
                 ", fastforward"
#endif
                 "; classical and fastforward build their map of the mapping split in memory")
      ->check(CLI::Validator(
          [](const std::string& input) {
            const std::string empty_entry = emptyListEntryProblem(input);
            return empty_entry.empty() ? methodListProblem(splitList(input)) : empty_entry;
          },
          "LIST"));
  cmd->add_option("--map", args->map_path,
                  "Evaluate this map file from 'ffloc map' (any method), exactly as 'ffloc localize' runs it; "
                  "its row is named <method>@map; without --methods no other method runs");
  cmd->add_option("--json", args->json_path,
                  "Write the summary JSON here; the per-frame CSV (<stem>.frames.csv) and the markdown table "
                  "(<stem>.md) go beside it unless --csv/--markdown say otherwise");
  cmd->add_option("--csv", args->csv_path, "Write the per-frame CSV here");
  cmd->add_option("--markdown", args->markdown_path, "Write the markdown table here");
  cmd->add_option("--html", args->html_path,
                  "Write a self-contained HTML report here: the table, cumulative error curves, errors per query, "
                  "a top view of the cameras and the worst queries' thumbnails (docs/report.md)");
  cmd->add_option("--outliers", args->outliers, "oracle-depth: fraction of 3D points replaced at random")
      ->capture_default_str();
  cmd->add_option("--noise-px", args->noise_px, "oracle-depth: Gaussian pixel noise (sigma, px)")->capture_default_str();
  cmd->add_option("--point-noise", args->point_noise,
                  "oracle-depth: Gaussian noise on the 3D points (sigma, dataset units)")
      ->capture_default_str();
  cmd->add_option("--stride", args->stride, "oracle-depth: use every n-th pixel of the depth map")
      ->capture_default_str()
      ->check(atLeast(1));
  cmd->add_option("--inlier-threshold", args->inlier_threshold_px, "RANSAC inlier threshold (px)")
      ->capture_default_str();
  cmd->add_option("--confidence-threshold", args->confidence_threshold,
                  "Drop correspondences with confidence below this (the paper's tau)")
      ->capture_default_str();
  cmd->add_option("--max-correspondences", args->max_correspondences,
                  "Subsample to at most this many correspondences before PnP")
      ->check(wholeNumber())
      ->capture_default_str();
  cmd->add_option("--min-correspondences", args->min_correspondences,
                  "When fewer pass the confidence threshold, use this many most confident ones (0: strict threshold)")
      ->check(wholeNumber())
      ->capture_default_str();
  cmd->add_option("--max-queries", args->max_queries, "Evaluate at most this many evenly spaced queries (0 = all)")
      ->check(wholeNumber())
      ->capture_default_str();
  addQueryOptions(*cmd, args->query);
  cmd->add_flag("--no-depth", args->no_depth, "classical: triangulate every point, even where frames have depth");
  cmd->add_option("--poses", args->poses_path, "Write the estimated poses as an hloc pose list (one dataset and method)");
#ifdef FFLOC_WITH_TORCH
  addModelOptions(*cmd, args->model, "fastforward: weights (see 'ffloc map --help')");
#endif
  cmd->add_option("--ply", args->ply_path,
                  "Write a PLY (one dataset; the map's poses, else fastforward's when it runs, else the first "
                  "method's): mapping frames grey, ground truth green, estimates blue, and for a localizer its last "
                  "query's points red");
  cmd->add_option("--protocol", args->protocol,
                  "The paper's setting for a benchmark (wayspots, indoor6, rio10, cambridge, 7scenes): top-K, N and "
                  "7-Scenes' mapping-frame thinning; --top-k/--features override it (docs/protocols.md)");
  cmd->add_flag("--quiet", args->quiet, "No progress bar");
  for (const char* path_flag : {"--map", "--json", "--csv", "--markdown", "--html", "--poses", "--ply"})
    cmd->get_option(path_flag)->check(nonEmptyPath());
  cmd->callback([args, cmd, &run] {
    args->method_flags_given = flagsGiven(*cmd, methodSettingOfFlag());
    args->evaluation_flags_given = flagsGiven(*cmd, evaluationMethodOfFlag());
    // PnP's settings that evaluation studies and 'ffloc localize' does not take.
    for (const char* flag : {"--inlier-threshold", "--confidence-threshold", "--max-correspondences",
                             "--min-correspondences"})
      if (cmd->get_option(flag)->count() > 0) args->study_only_pnp_flags_given.push_back(flag);
    run = [args] { return runEval(*args); };
  });
}

}  // namespace ffloc::cli
