#include <algorithm>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "command_model.h"
#include "command_options.h"
#include "commands.h"
#include "ffloc/core/error.h"
#include "ffloc/core/number_text.h"
#include "ffloc/core/threads.h"
#include "ffloc/data/dataset.h"
#include "ffloc/data/splits.h"
#include "ffloc/pipeline/map_building.h"

namespace ffloc::cli {
namespace {

struct MapArguments {
  std::string dataset;
  std::string format = "auto";
  std::string method = "classical";
  ModelArguments model;
  std::string output;
  bool append = false;
  bool no_depth = false;
  int max_image_size = SiftOptions().max_image_size;
  int max_features = SiftOptions().max_features;
  bool vlad = false;
  bool quiet = false;
  SetMapBuildOptions options_given;  // of those that apply to one method only, or not with --append
};

void printSummary(size_t added, size_t duplicates, double seconds, size_t images, const std::string& output) {
  std::cout << "mapped " << added << " images";
  if (duplicates > 0) std::cout << " (" << duplicates << " already in the map, skipped)";
  std::cout << " in " << std::fixed << std::setprecision(2) << seconds << " s";
  if (added > 0) std::cout << " (" << std::setprecision(3) << seconds / added << " s/image)";
  std::cout << "; " << output << " holds " << images << " images, " << std::setprecision(1)
            << std::filesystem::file_size(output) / (1024.0 * 1024.0) << " MiB\n";
}

// The mapping images' intrinsics, for queries of the same camera to be given alike: a reader may
// not take them as the dataset's file says (7-Scenes' colour images get 525 px where its file says
// the depth camera's 585), and an outside review's query given the file's values was 14 cm off.
void printMappedIntrinsics(const Scene& scene, bool every_frame) {
  std::vector<Intrinsics> distinct;
  for (const size_t i : every_frame ? scene.indices(Split::kUnassigned) : scene.mappingIndices()) {
    const Intrinsics& k = scene.frames[i].intrinsics;
    const bool seen = std::any_of(distinct.begin(), distinct.end(), [&](const Intrinsics& other) {
      return other.fx == k.fx && other.fy == k.fy && other.cx == k.cx && other.cy == k.cy &&
             other.width == k.width && other.height == k.height && other.distortion == k.distortion;
    });
    if (!seen) distinct.push_back(k);
  }
  if (distinct.empty()) return;
  const Intrinsics& k = distinct.front();
  std::cout << (distinct.size() == 1 ? "intrinsics of the mapping images: " : "intrinsics of the first mapping image: ")
            << formatNumber(k.fx) << "," << formatNumber(k.fy) << "," << formatNumber(k.cx) << "," << formatNumber(k.cy)
            << " at " << k.width << "x" << k.height;
  // A query of this camera given the four numbers alone was 40 times farther off on fox (an
  // outside probe): its distortion is printed as --distortion takes it.
  if (!k.distortion.empty()) {
    std::cout << ", distortion ";
    for (size_t i = 0; i < k.distortion.size(); ++i) std::cout << (i ? "," : "") << formatNumber(k.distortion[i]);
  }
  if (distinct.size() > 1) std::cout << " (" << distinct.size() << " different ones among them)";
  std::cout << "\n";
}

int runMap(const MapArguments& args) {
  MapBuildOptions options;
  options.method = parseLocalizationMethod(args.method);
  options.append = args.append;
  // A flag that the run would ignore is refused before any work.
  if (const std::string problem = ignoredOptionProblem(options, args.options_given); !problem.empty())
    throw InputError(problem);
  setLibraryThreadCount(args.model.threads);
  options.classical.use_depth = !args.no_depth;
  options.classical.sift.max_image_size = args.max_image_size;
  options.classical.sift.max_features = args.max_features;
  options.classical.quiet = args.quiet;
  options.fastforward.quiet = args.quiet;
  options.fastforward.vlad = args.vlad;
  const Scene scene = loadDataset(args.dataset, args.format);
  const MapBuildReport report = buildMap(scene, args.output, options, [&] { return loadCommandModel(args.model); });
  if (report.every_frame)
    std::cerr << "note: " << args.dataset << " has no split, so every frame was mapped (" << kMappingSplitFile
              << " in its folder chooses them)\n";
  if (report.previous_images > 0)
    std::cerr << "appended to " << args.output << " (" << report.previous_images << " images before)\n";
  if (options.method == LocalizationMethod::kClassical) {
    if (!report.featureless.empty()) {
      // Named, so that they can be found (a probe got only their count).
      const size_t shown = std::min<size_t>(report.featureless.size(), 5);
      std::cerr << report.featureless.size() << " images with fewer than two SIFT keypoints left out: ";
      for (size_t i = 0; i < shown; ++i) std::cerr << (i ? ", " : "") << report.featureless[i];
      if (shown < report.featureless.size()) std::cerr << " and " << report.featureless.size() - shown << " more";
      std::cerr << "\n";
    }
  }
  // A dataset with depth for some frames only mapped the others without a word.
  if (report.added_without_points > 0)
    std::cerr << "warning: " << report.added_without_points << " of the " << report.added
              << " images added have no depth, so their tokens carry no 3D points and the model cannot place a "
                 "query on them\n";
  printSummary(report.added, report.skipped_duplicates, report.seconds, report.images, args.output);
  // The summary's second line, on stdout beside the first (it was on stderr, an outside probe).
  // "depth where the frames have it, triangulated elsewhere" was printed for --no-depth and for
  // datasets without depth alike.
  if (options.method == LocalizationMethod::kClassical) {
    // An append's counts are of the images it added: "0 points" after one that added none read as
    // the whole map's (an outside probe).
    if (report.previous_images > 0) std::cout << "in the " << report.added << " images added: ";
    std::cout << report.points << " points (" << report.points_from_depth << " lifted from depth, "
              << report.points - report.points_from_depth << " triangulated"
              << (args.no_depth ? ": --no-depth" : "") << "), " << report.links << " links\n";
  }
  printMappedIntrinsics(scene, report.every_frame);
  return 0;
}

}  // namespace

void registerMapCommand(CLI::App& app, CommandRun& run) {
  auto args = std::make_shared<MapArguments>();
  CLI::App* cmd = app.add_subcommand(
      "map",
      "Build a map of a dataset's mapping split (every frame where the dataset has no split), in one versioned, "
      "checksummed file. classical (the default): SIFT keypoints and descriptors, links between the images, a 3D "
      "point per keypoint (lifted with the frame's depth where it has depth, triangulated elsewhere), a VLAD "
      "vocabulary. fastforward (experimental): encoder tokens (fp16) and global descriptors of every image for the "
      "network.");
  cmd->add_option("--dataset", args->dataset, "Dataset folder (its mapping split is mapped, or every frame where it has no split)")
      ->required()
      ->check(nonEmptyPath());
  cmd->add_option("--format", args->format, "Dataset format (auto detects)")->capture_default_str();
  cmd->add_option("--method", args->method, "classical or fastforward")->capture_default_str();
  addModelOptions(*cmd, args->model,
                  "fastforward: 'default' (the shipped model, models/MODEL_CARD.md; FFLOC_MODEL overrides), a "
                  "FastForward checkpoint, a DUSt3R checkpoint (.pth or safetensors; initialises FastForward, whose "
                  "ray MLP and map head are then untrained) or random:<tiny|small|large>[:seed] for tests");
  cmd->add_option("-o,--output", args->output, "Map file to write (atomically)")->required()->check(nonEmptyPath());
  cmd->add_flag("--append", args->append,
                "Add the dataset's images to an existing map of the same method (and model); images already in it "
                "(by name) are skipped and the earlier ones kept as they are");
  cmd->add_flag("--no-depth", args->no_depth, "classical: triangulate every point, even where frames have depth");
  cmd->add_option("--max-image-size", args->max_image_size,
                  "classical: SIFT runs on images shrunk to this long side (queries too: the map records it)")
      ->capture_default_str();
  cmd->add_option("--max-features", args->max_features, "classical: SIFT keypoints per image, strongest first (queries too)")
      ->capture_default_str();
  cmd->add_flag("--vlad", args->vlad,
                "fastforward: also store the classical VLAD descriptor of every image, for 'localize --retrieval vlad'");
  cmd->add_flag("--quiet", args->quiet, "No progress bar");
  cmd->callback([args, cmd, &run] {
    const std::pair<const char*, const char*> options[] = {{"--model", "model"},
                                                           {"--dtype", "dtype"},
                                                           {"--no-depth", "use_depth"},
                                                           {"--max-image-size", "max_image_size"},
                                                           {"--max-features", "max_features"},
                                                           {"--vlad", "vlad"}};
    for (const auto& [flag, option] : options)
      if (cmd->count(flag) > 0) args->options_given.push_back(option);
    run = [args] { return runMap(*args); };
  });
}

}  // namespace ffloc::cli
