#include <algorithm>
#include <iostream>
#include <memory>
#include <sstream>

#include "commands.h"
#include "ffloc/core/error.h"
#include "ffloc/data/dataset.h"
#include "ffloc/eval/evaluator.h"
#include "ffloc/eval/exports.h"
#include "ffloc/eval/oracle_depth_source.h"
#include "ffloc/eval/protocol.h"
#include "ffloc/eval/report.h"
#include "ffloc/eval/sift_baseline_source.h"
#ifdef FFLOC_WITH_TORCH
#include "ffloc/model/torch_threads.h"
#include "ffloc/pipeline/fastforward_source.h"
#include "ffloc/pipeline/model_options.h"
#include "ffloc/pipeline/scene_ply.h"
#endif

namespace ffloc::cli {
namespace {

struct EvalArguments {
  std::vector<std::string> datasets;
  std::string format = "auto";
  std::string methods = "oracle-depth";
  std::string json_path, csv_path, markdown_path;
  std::string solver = "lo-ransac";
  double outliers = 0.0;
  double noise_px = 0.0;
  double point_noise = 0.0;
  int stride = 4;
  size_t max_queries = 0;
  uint64_t seed = 0;
  double inlier_threshold_px = PnpOptions().inlier_threshold_px;
  float confidence_threshold = PnpOptions().confidence_threshold;
  size_t max_correspondences = PnpOptions().max_correspondences;
  size_t min_correspondences = PnpOptions().min_correspondences;
  std::string model = "default", map_path, dtype = "f32";
  std::string selection = "retrieval";
  size_t top_k = 10;        // the paper's indoor setting
  int64_t features = 1500;
  std::string poses_path, ply_path;
  std::string protocol;
  int threads = 0;
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
// Loaded once and shared by the sources of every dataset.
std::shared_ptr<const LoadedModel> sharedModel(const EvalArguments& args) {
  static std::shared_ptr<const LoadedModel> model;
  if (!model) {
    setTorchThreadCount(args.threads);
    ModelLoadOptions options;
    options.dtype = parseNetworkDtype(args.dtype);
    model = std::make_shared<const LoadedModel>(loadModel(args.model, options));
  }
  return model;
}
#endif

std::unique_ptr<CoordinateSource> makeSource(const std::string& method, const EvalArguments& args) {
  if (method == "oracle-depth") {
    OracleDepthOptions options;
    options.outlier_fraction = args.outliers;
    options.pixel_noise_px = args.noise_px;
    options.point_noise = args.point_noise;
    options.stride = args.stride;
    options.seed = args.seed;
    return std::make_unique<OracleDepthSource>(options);
  }
  if (method == "sift-baseline") {
    SiftBaselineOptions options;
    options.seed = args.seed;
    return std::make_unique<SiftBaselineSource>(options);
  }
#ifdef FFLOC_WITH_TORCH
  if (method == "fastforward") {
    FastForwardSourceOptions options;
    options.localize.top_k = args.top_k;
    options.localize.num_features = args.features;
    options.localize.seed = args.seed;
    options.localize.selection = parseImageSelection(args.selection);
    options.map_path = args.map_path;
    options.mapping.quiet = args.quiet;
    return std::make_unique<FastForwardSource>(sharedModel(args), options);
  }
#endif
  throw InputError("--methods: unknown method '" + method + "' (known: oracle-depth, sift-baseline, fastforward)");
}

void runEval(const EvalArguments& args) {
  std::vector<std::string> methods = splitList(args.methods);
  if (methods.empty()) throw InputError("--methods: empty list");
  if (args.outliers < 0 || args.outliers > 1) throw InputError("--outliers: must be in [0, 1]");
  if (!args.map_path.empty() && args.datasets.size() != 1) throw InputError("--map: a map serves exactly one dataset");
  if (!args.poses_path.empty() && (methods.size() != 1 || args.datasets.size() != 1))
    throw InputError("--poses: needs exactly one dataset and one method");
  if (!args.ply_path.empty() && args.datasets.size() != 1) throw InputError("--ply: needs exactly one dataset");
#ifdef FFLOC_WITH_TORCH
  // The PLY shows one method's poses: fastforward's when it runs (with its predicted points).
  const bool has_fastforward = std::find(methods.begin(), methods.end(), "fastforward") != methods.end();
  const std::string ply_method = has_fastforward ? "fastforward" : methods.front();
#endif

  EvaluationOptions options;
  options.pnp.solver = parsePnpSolver(args.solver);
  options.pnp.seed = args.seed;
  options.pnp.inlier_threshold_px = args.inlier_threshold_px;
  options.pnp.confidence_threshold = args.confidence_threshold;
  options.pnp.max_correspondences = args.max_correspondences;
  options.pnp.min_correspondences = args.min_correspondences;
  options.max_queries = args.max_queries;
  options.quiet = args.quiet;

  std::vector<FrameResult> all_frames;
  std::vector<MethodSummary> summaries;
  std::vector<std::string> non_metric;
  for (const std::string& dataset : args.datasets) {
    Scene scene = loadDataset(dataset, args.format);
    if (!args.protocol.empty()) thinMappingFrames(scene, benchmarkProtocol(args.protocol).mapping_stride);
    if (!scene.metric) non_metric.push_back(scene.name);
    for (const std::string& method : methods) {
      auto source = makeSource(method, args);
      const std::vector<FrameResult> frames = evaluate(scene, *source, options);
      summaries.push_back(summarize(frames));
      all_frames.insert(all_frames.end(), frames.begin(), frames.end());
#ifdef FFLOC_WITH_TORCH
      if (!args.ply_path.empty() && method == ply_method) {
        // FastForward adds the predicted points of the last query.
        const auto* fastforward = dynamic_cast<const FastForwardSource*>(source.get());
        evaluationPly(scene, frames, fastforward ? &fastforward->lastPrediction().correspondences : nullptr,
                      options.pnp.confidence_threshold)
            .write(args.ply_path);
        std::cerr << "wrote " << args.ply_path << "\n";
      }
#endif
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
  if (!args.protocol.empty()) std::cerr << describeProtocol(benchmarkProtocol(args.protocol));
  std::string csv_path = args.csv_path, markdown_path = args.markdown_path;
  if (!args.json_path.empty()) {
    writeTextFile(args.json_path, summaryJson(summaries).dump(2) + "\n");
    const std::filesystem::path stem = std::filesystem::path(args.json_path).replace_extension();
    if (csv_path.empty()) csv_path = stem.string() + ".frames.csv";
    if (markdown_path.empty()) markdown_path = stem.string() + ".md";
    std::cerr << "wrote " << args.json_path << "\n";
  }
  if (!csv_path.empty()) {
    writeTextFile(csv_path, perFrameCsv(all_frames));
    std::cerr << "wrote " << csv_path << "\n";
  }
  if (!markdown_path.empty()) {
    writeTextFile(markdown_path, table);
    std::cerr << "wrote " << markdown_path << "\n";
  }
  if (!args.poses_path.empty()) {
    writeTextFile(args.poses_path, hlocPoseList(all_frames));
    std::cerr << "wrote " << args.poses_path << "\n";
  }
}

}  // namespace

void registerEvalCommand(CLI::App& app) {
  auto args = std::make_shared<EvalArguments>();
  CLI::App* cmd = app.add_subcommand(
      "eval", "Localise every query frame of one or more datasets with one or more methods, and report pose "
              "accuracy (medians; % within 5cm/5deg, 10cm/10deg, 20cm/20deg, 10cm/1deg, 25cm/5deg) and latency.");
  cmd->add_option("--dataset", args->datasets, "Dataset folder(s); the format is detected (comma-separated for several)")
      ->required()
      ->delimiter(',');
  cmd->add_option("--format", args->format, "Dataset format: auto, " + [] {
        std::string s;
        for (const auto& f : datasetFormats()) s += (s.empty() ? "" : ", ") + f;
        return s;
      }())->capture_default_str();
  cmd->add_option("--methods", args->methods, "Comma-separated coordinate sources: oracle-depth, sift-baseline, fastforward")->capture_default_str();
  cmd->add_option("--json", args->json_path,
                  "Write the summary JSON here; the per-frame CSV (<stem>.frames.csv) and the markdown table "
                  "(<stem>.md) go beside it unless --csv/--markdown say otherwise");
  cmd->add_option("--csv", args->csv_path, "Write the per-frame CSV here");
  cmd->add_option("--markdown", args->markdown_path, "Write the markdown table here");
  cmd->add_option("--outliers", args->outliers, "oracle-depth: fraction of 3D points replaced at random")
      ->capture_default_str();
  cmd->add_option("--noise-px", args->noise_px, "oracle-depth: Gaussian pixel noise (sigma, px)")->capture_default_str();
  cmd->add_option("--point-noise", args->point_noise,
                  "oracle-depth: Gaussian noise on the 3D points (sigma, dataset units)")
      ->capture_default_str();
  cmd->add_option("--stride", args->stride, "oracle-depth: use every n-th pixel of the depth map")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->add_option("--solver", args->solver, "PnP-RANSAC solver: lo-ransac or opencv-usac")->capture_default_str();
  cmd->add_option("--inlier-threshold", args->inlier_threshold_px, "RANSAC inlier threshold (px)")
      ->capture_default_str();
  cmd->add_option("--confidence-threshold", args->confidence_threshold,
                  "Drop correspondences with confidence below this (the paper's tau)")
      ->capture_default_str();
  cmd->add_option("--max-correspondences", args->max_correspondences,
                  "Subsample to at most this many correspondences before PnP")
      ->capture_default_str();
  cmd->add_option("--min-correspondences", args->min_correspondences,
                  "When fewer pass the confidence threshold, use this many most confident ones (0: strict threshold)")
      ->capture_default_str();
  cmd->add_option("--max-queries", args->max_queries, "Evaluate at most this many evenly spaced queries (0 = all)")
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "Seed for sampling, noise and RANSAC")->capture_default_str();
  cmd->add_option("--poses", args->poses_path, "Write the estimated poses as an hloc pose list (one dataset and method)");
#ifdef FFLOC_WITH_TORCH
  cmd->add_option("--model", args->model, "fastforward: weights (see 'ffloc map --help')")->capture_default_str();
  cmd->add_option("--map", args->map_path, "fastforward: a map from 'ffloc map' (default: map the mapping split in memory)");
  cmd->add_option("--top-k", args->top_k, "fastforward: mapping images per query")->capture_default_str();
  cmd->add_option("--features", args->features, "fastforward: map tokens per query")->capture_default_str();
  cmd->add_option("--selection", args->selection, "fastforward: retrieval, uniform or random")->capture_default_str();
  cmd->add_option("--dtype", args->dtype, "fastforward: network precision f32, or bf16 (encoder, decoder and DPT head)")
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "fastforward: libtorch threads (0 = all cores)")->capture_default_str();
  cmd->add_option("--ply", args->ply_path,
                  "Write a PLY (one dataset; fastforward's poses when it runs, else the first method's): mapping cameras grey, ground truth green, estimates blue, "
                  "fastforward's predicted points of the last query red");
#endif
  cmd->add_option("--protocol", args->protocol,
                  "The paper's setting for a benchmark (wayspots, indoor6, rio10, cambridge, 7scenes): top-K, N and "
                  "7-Scenes' mapping-frame thinning; --top-k/--features override it (docs/benchmarks.md)");
  cmd->add_flag("--quiet", args->quiet, "No progress bar");
  cmd->callback([args, cmd] {
    if (!args->protocol.empty()) {
      const BenchmarkProtocol& protocol = benchmarkProtocol(args->protocol);
      const auto* top_k = cmd->get_option_no_throw("--top-k");
      const auto* features = cmd->get_option_no_throw("--features");
      if (!top_k || top_k->count() == 0) args->top_k = protocol.top_k;
      if (!features || features->count() == 0) args->features = protocol.features;
    }
    runEval(*args);
  });
}

}  // namespace ffloc::cli
