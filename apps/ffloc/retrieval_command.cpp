#include <algorithm>
#include <chrono>
#include <functional>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <set>
#include <map>
#include <memory>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>

#include "command_model.h"
#include "command_options.h"
#include "commands.h"
#include "ffloc/classical/classical_map.h"
#include "ffloc/classical/sift_features.h"
#include "ffloc/classical/vlad.h"
#include "ffloc/core/clock.h"
#include "ffloc/core/error.h"
#include "ffloc/core/progress.h"
#include "ffloc/core/threads.h"
#include "ffloc/core/text_file_writer.h"
#include "ffloc/data/dataset.h"
#include "ffloc/io/image.h"
#include "ffloc/io/map_file.h"
#include "ffloc/localization/localizer.h"
#include "ffloc/pipeline/mapper.h"
#include "ffloc/model/model_loader.h"
#include "ffloc/pipeline/query_descriptor.h"
#include "ffloc/pipeline/token_vlad.h"
#include "ffloc/retrieval/image_selection.h"
#include "ffloc/retrieval/retrieval_recall.h"

namespace ffloc::cli {
namespace {

struct RetrievalArguments {
  std::string map_path;
  ModelArguments model;
  std::string dataset;
  std::string format = "auto";
  std::vector<size_t> top_k = {1, 5, 10, 20};
  size_t max_queries = 0;
  uint64_t seed = 0;
  std::string json_path;
  std::string retrieval;  // empty: the map's own (token-vlad for FastForward, vlad for classical)
  bool quiet = false;
  std::vector<std::string> fastforward_flags_given;
};

// What retrieval ranks, from a map of either method: its images, their global descriptors, and
// how a query is described the way the map's localizer describes it.
struct RankedMap {
  std::vector<std::string> names;
  std::vector<Pose> poses;
  std::vector<std::vector<float>> descriptors;
  std::function<std::vector<float>(const cv::Mat& rgb, const Frame& frame)> describe;
  std::string retrieval;
  std::string model_id, model_description;  // FastForward's; empty for a classical map
};

// The map's images that are the dataset's frames must have their poses, or the map and the
// queries live in different worlds and "nearest camera" means nothing (datasets share names like
// images/0000.jpg, so the name alone does not tell). Images of other datasets, appended to the
// map, may be among them (an appended map was refused, found by an outside probe); one at least
// must be a frame of this one.
void checkMapAgainstDataset(const RankedMap& map, const std::string& map_path, const Scene& scene) {
  std::map<std::string, const Frame*> frames;
  for (const Frame& frame : scene.frames) frames[frame.name] = &frame;
  size_t shared = 0;
  for (size_t i = 0; i < map.names.size(); ++i) {
    const auto found = frames.find(map.names[i]);
    if (found == frames.end()) continue;
    const Pose& pose = found->second->camera_to_world;
    const double tolerance = 1e-6 * std::max(1.0, pose.t.norm());
    if ((map.poses[i].matrix() - pose.matrix()).cwiseAbs().maxCoeff() > tolerance)
      throwInputError(map_path, 0, "image '" + map.names[i] + "': pose differs from that frame's in dataset " +
                                       scene.root.string() + " (the map was built from another dataset)");
    ++shared;
  }
  if (shared == 0)
    throwInputError(map_path, 0, "none of its " + std::to_string(map.names.size()) + " images is a frame of dataset " +
                                     scene.root.string() + " (the map was built from another dataset)");
}

std::vector<float> floats(const Eigen::VectorXf& vector) { return {vector.data(), vector.data() + vector.size()}; }

// A classical map ranks its images by their VLAD descriptors, as ClassicalLocalizer does.
RankedMap classicalRankedMap(const RetrievalArguments& args) {
  for (const std::string& flag : args.fastforward_flags_given)
    throw InputError(flag + ": applies to FastForward maps; " + args.map_path +
                     " is a classical map, which ranks its images by their VLAD descriptors");
  setLibraryThreadCount(args.model.threads);  // SIFT's, as no network loads to set them
  auto map = std::make_shared<const ClassicalMap>(readClassicalMap(args.map_path));
  RankedMap ranked;
  ranked.retrieval = "vlad";
  for (const ClassicalMapImage& image : map->images) {
    ranked.names.push_back(image.name);
    ranked.poses.push_back(image.camera_to_world);
    ranked.descriptors.push_back(floats(image.global_descriptor));
  }
  ranked.describe = [map](const cv::Mat& rgb, const Frame& frame) {
    return floats(map->vocabulary.describe(extractSiftFeatures(rgb, frame.intrinsics, frame.name, map->sift).descriptors));
  };
  return ranked;
}

RankedMap fastForwardRankedMap(const RetrievalArguments& args) {
  auto model = std::make_shared<const LoadedModel>(loadCommandModel(args.model));
  const MapFile map = readMapFile(args.map_path, model->id);
  if (map.images.empty()) throwInputError(args.map_path, 0, "map holds no images");
  const int64_t enc_dim = model->model->config().dust3r.enc_dim;
  if (map.token_dim != enc_dim)
    throwInputError(args.map_path, 0, "token width " + std::to_string(map.token_dim) + " differs from the model's " +
                                          std::to_string(enc_dim));
  RankedMap ranked;
  ranked.retrieval = args.retrieval.empty() ? "token-vlad" : args.retrieval;
  ranked.model_id = model->id;
  ranked.model_description = model->description;
  const FastForwardRetrieval retrieval = parseFastForwardRetrieval(ranked.retrieval);
  if (retrieval == FastForwardRetrieval::kVlad && map.vlad_centres.empty())
    throwInputError(args.map_path, 0, "the map has no VLAD vocabulary (build it with 'ffloc map --vlad')");
  std::shared_ptr<const TokenVlad> token_vlad;
  if (retrieval == FastForwardRetrieval::kTokenVlad) token_vlad = std::make_shared<const TokenVlad>(map);
  const size_t length = static_cast<size_t>(2 * enc_dim);
  for (size_t i = 0; i < map.images.size(); ++i) {
    const MapImage& image = map.images[i];
    if (retrieval == FastForwardRetrieval::kEncoder && image.descriptor.size() != length)
      throwInputError(args.map_path, 0, "image '" + image.name + "': descriptor has " +
                                            std::to_string(image.descriptor.size()) + " values, the model's has " +
                                            std::to_string(length));
    ranked.names.push_back(image.name);
    ranked.poses.push_back(image.camera_to_world);
    if (token_vlad) {
      ranked.descriptors.push_back(floats(token_vlad->imageDescriptors()[i]));
    } else {
      ranked.descriptors.push_back(retrieval == FastForwardRetrieval::kVlad ? image.vlad_descriptor : image.descriptor);
    }
  }
  auto vocabulary = std::make_shared<const VladVocabulary>(
      map.vlad_centres.empty() ? VladVocabulary()
                               : VladVocabulary(Eigen::Map<const VladVocabulary::RowMatrixXf>(
                                     map.vlad_centres.data(), static_cast<Eigen::Index>(map.vlad_centres.size() / 128), 128)));
  // The map does not record its preprocessing and pooling settings; `ffloc map` uses the defaults.
  ranked.describe = [model, token_vlad, vocabulary, retrieval](const cv::Mat& rgb, const Frame& frame) {
    const MappingOptions mapping_options;
    if (retrieval == FastForwardRetrieval::kVlad)
      return floats(vocabulary->describe(extractSiftFeatures(rgb, frame.intrinsics, frame.name).descriptors));
    if (token_vlad)
      return floats(token_vlad->describe(
          queryEncoding(*model->model, rgb, frame.intrinsics, frame.name, mapping_options.long_side).tokens));
    return queryDescriptor(*model->model, rgb, frame.intrinsics, frame.name, mapping_options.long_side,
                           mapping_options.descriptor);
  };
  return ranked;
}

std::string fixed(double value, int digits) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(digits) << value;
  return out.str();
}

void printTable(const RetrievalRecall& result, size_t queries, size_t mapping) {
  std::cout << "recall@K of the pose-nearest mapping camera (" << queries << " queries, " << mapping
            << " mapping images)\n";
  std::cout << "    K  retrieval  uniform  random\n";
  for (const RecallAtK& r : result.recall)
    std::cout << std::setw(5) << r.k << "  " << std::setw(9) << fixed(r.retrieval, 3) << "  " << std::setw(7)
              << fixed(r.uniform, 3) << "  " << std::setw(6) << fixed(r.random, 3) << "\n";
  std::cout << "median rank of the nearest camera under retrieval: " << fixed(result.median_rank, 1) << " of "
            << mapping << "\n";
}

void runRetrieval(const RetrievalArguments& args) {
  if (args.top_k.empty()) throw InputError("--top-k: no K given");
  std::set<size_t> seen;
  for (size_t k : args.top_k) {
    if (k == 0) throw InputError("--top-k: K must be positive");
    // A K given twice printed its row twice.
    if (!seen.insert(k).second) throw InputError("--top-k: " + std::to_string(k) + " given twice");
  }
  // The recall JSON given the map's path replaced the map, exit 0 (probe).
  refuseOutputOverInputs("--json", args.json_path, {{"the map (--map)", args.map_path}}, {args.dataset});
  checkOutputPath("--json", args.json_path);  // before the run, as eval and localize check theirs

  const RankedMap map = parseLocalizationMethod(readMapHeader(args.map_path).method) == LocalizationMethod::kClassical
                            ? classicalRankedMap(args)
                            : fastForwardRankedMap(args);
  if (map.names.empty()) throwInputError(args.map_path, 0, "map holds no images");
  // Such a K retrieves every image: its recall is 1 whatever the descriptors.
  for (size_t k : args.top_k) {
    if (k >= map.names.size()) {
      std::cerr << "note: --top-k " << k << " is at least the map's " << map.names.size()
                << " images: every image is retrieved, so its recall is 1 by construction\n";
    }
  }
  const Scene scene = loadDataset(args.dataset, args.format);
  requireSplits(scene);
  checkMapAgainstDataset(map, args.map_path, scene);
  std::vector<size_t> query_frames = scene.queryIndices();
  if (args.max_queries > 0 && args.max_queries < query_frames.size()) {
    std::vector<size_t> kept;
    for (size_t i : uniformSelection(query_frames.size(), args.max_queries)) kept.push_back(query_frames[i]);
    query_frames = kept;
  }

  std::vector<Pose> query_poses;
  std::vector<std::vector<float>> query_descriptors;
  ProgressBar progress("describing queries", query_frames.size(), args.quiet);
  double encoding_seconds = 0;
  for (size_t i = 0; i < query_frames.size(); ++i) {
    const Frame& frame = scene.frames[query_frames[i]];
    const auto start = std::chrono::steady_clock::now();
    query_descriptors.push_back(map.describe(readImageRgb(frame.image_path), frame));
    encoding_seconds += secondsSince(start);
    query_poses.push_back(frame.camera_to_world);
    progress.update(i + 1);
  }
  progress.finish();

  RetrievalRecallOptions options;
  options.top_k = args.top_k;
  options.seed = args.seed;
  const RetrievalRecall result =
      measureRetrievalRecall(map.poses, query_poses, map.descriptors, query_descriptors, options);
  std::cout << "dataset " << scene.root.string() << ", map " << args.map_path << "\n";
  printTable(result, query_frames.size(), map.names.size());
  const double encoding_ms = 1e3 * encoding_seconds / static_cast<double>(query_frames.size());
  std::cout << "reading, preparing and encoding a query: " << fixed(encoding_ms, 1) << " ms per query\n";

  if (args.json_path.empty()) return;
  nlohmann::json recall = nlohmann::json::array();
  for (const RecallAtK& r : result.recall)
    recall.push_back({{"k", r.k}, {"retrieval", r.retrieval}, {"uniform", r.uniform}, {"random", r.random}});
  const size_t largest_k = *std::max_element(args.top_k.begin(), args.top_k.end());
  nlohmann::json per_query = nlohmann::json::array();
  for (size_t q = 0; q < query_frames.size(); ++q) {
    const std::vector<size_t> top = topKBySimilarity(map.descriptors, query_descriptors[q], largest_k);
    nlohmann::json top_names = nlohmann::json::array();
    for (size_t index : top) top_names.push_back(map.names[index]);
    per_query.push_back({{"name", scene.frames[query_frames[q]].name},
                         {"nearest", map.names[result.nearest[q]]},
                         {"rank", result.rank[q]},
                         {"top", top_names}});
  }
  const nlohmann::json out = {{"dataset", scene.root.string()},
                              {"map", args.map_path},
                              {"model_id", map.model_id},
                              {"model", map.model_description},
                              {"mapping_images", map.names.size()},
                              {"queries", query_frames.size()},
                              {"random_seed", args.seed},
                              {"retrieval", map.retrieval},
                              {"recall", recall},
                              {"median_rank", result.median_rank},
                              {"encoding_ms_per_query", encoding_ms},
                              {"per_query", per_query}};
  writeTextFile(args.json_path, out.dump(2) + "\n");
  std::cerr << "wrote " << args.json_path << "\n";
}

}  // namespace

void registerRetrievalCommand(CLI::App& app, CommandRun& run) {
  auto args = std::make_shared<RetrievalArguments>();
  CLI::App* cmd = app.add_subcommand(
      "retrieval",
      "Measure image retrieval on a dataset's query split: for each K, the fraction of queries whose K mapping "
      "images selected by global-descriptor retrieval (and, for reference, by uniform and random selection) contain "
      "the mapping camera nearest to the query's ground-truth pose; also the median rank of that camera.");
  cmd->add_option("--map", args->map_path, "Map file from 'ffloc map' built from this dataset (either method)")->required();
  addModelOptions(*cmd, args->model, "The model the map was built with (same forms as for 'ffloc map')");
  cmd->add_option("--dataset", args->dataset, "Dataset folder; its query split is measured")->required();
  cmd->add_option("--format", args->format, "Dataset format (auto detects)")->capture_default_str();
  // CLI11 showed the default list space-separated and the type's range from 0, which is refused.
  cmd->add_option("--top-k", args->top_k, "Comma-separated K values, each at least 1")
      ->delimiter(',')
      ->check(wholeNumber().description(""))
      ->type_name("K,...")
      ->default_str("1,5,10,20");
  cmd->add_option("--max-queries", args->max_queries, "Measure at most this many evenly spaced queries (0 = all)")
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "Seed of the random selection")->check(wholeNumber())->capture_default_str();
  cmd->add_option("--retrieval", args->retrieval,
                  "FastForward maps: what ranks the mapping images: encoder (the model's pooled tokens), vlad (the "
                  "classical descriptor; the map must have been built with --vlad) or token-vlad (a VLAD of the "
                  "model's tokens, its vocabulary learned from the map's; the default). A classical map ranks by "
                  "its VLAD descriptors, as it localizes");
  cmd->add_option("--json", args->json_path, "Write the recall table and per-query ranks as JSON here");
  cmd->add_flag("--quiet", args->quiet, "No progress bar");
  for (const char* path_flag : {"--map", "--dataset", "--json"}) cmd->get_option(path_flag)->check(nonEmptyPath());
  cmd->callback([args, cmd, &run] {
    for (const char* flag : {"--model", "--dtype", "--retrieval"})
      if (cmd->count(flag) > 0) args->fastforward_flags_given.push_back(flag);
    run = [args] {
      runRetrieval(*args);
      return 0;
    };
  });
}

}  // namespace ffloc::cli
